"""Every registered controller passes the protocol checker; the registry helps with typos."""

from __future__ import annotations

import pytest

from scftc_cli.baselines.base import controller_info, make_controller, registry
from scftc_cli.baselines.checker import check_controller
from scftc_cli.errors import UnknownNameError


@pytest.mark.parametrize("name", sorted(registry()))
def test_every_registered_controller_passes_the_checker(name):
    check_controller(make_controller(name))


def test_oracles_are_flagged_privileged_and_others_are_not():
    entries = registry()
    assert entries["teacher"].privileged and entries["bias_oracle"].privileged
    assert not entries["pd"].privileged


def test_unknown_name_suggests_the_closest():
    with pytest.raises(UnknownNameError, match="did you mean `teacher`"):
        controller_info("teacher_")
    with pytest.raises(KeyError):  # catchable as the built-in it subclasses
        controller_info("nope")
