"""Every registered controller passes the protocol checker; the registry is data, helps with
typos and refuses a controller on a benchmark version it does not fly."""

from __future__ import annotations

import subprocess
import sys

import pytest

from scftc_cli.baselines.checker import check_controller
from scftc_cli.errors import UnknownNameError
from scftc_cli.registry import controller_spec, make_controller, registry
from scftc_cli.versions import all_versions

BUILTINS = [entry for version in all_versions() for entry in version.controllers]


@pytest.mark.parametrize("entry", BUILTINS, ids=lambda e: f"{e.name}-{e.benchmark}")
def test_every_registered_controller_passes_the_checker(entry):
    check_controller(make_controller(entry.name, entry.benchmark), benchmark=entry.benchmark)


def test_a_name_is_unique_within_each_version():
    for version in all_versions():
        names = [c.name for c in version.controllers]
        assert len(names) == len(set(names)), version.name


@pytest.mark.parametrize("entry", BUILTINS, ids=lambda e: e.name)
def test_the_registry_says_what_the_class_is(entry):
    cls = entry.load()
    assert cls.privileged is entry.privileged
    for artifact in entry.artifact_paths():
        assert artifact.is_file(), artifact


def test_oracles_are_flagged_privileged_and_listed_last():
    entries = list(registry().values())
    assert [e.name for e in entries if e.privileged] == ["teacher", "bias_oracle"]
    assert entries[-2:] == [e for e in entries if e.privileged]
    assert not registry()["pd"].privileged


def test_unknown_name_suggests_the_closest():
    with pytest.raises(UnknownNameError, match="did you mean `teacher`"):
        controller_spec("teacher_")
    with pytest.raises(KeyError):  # catchable as the built-in it subclasses
        controller_spec("nope")


def test_listing_the_battery_imports_no_controller_module():
    code = (
        "import sys; from scftc_cli.registry import registry; "
        "from scftc_cli.versions import version_names; [registry(v) for v in version_names()]; "
        "loaded = [m for m in sys.modules if m.startswith('scftc_cli.baselines') or '.controllers' in m]; "
        "assert not loaded, loaded; "
        "assert 'torch' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
