"""Every built-in of every published version flies its pinned golden episodes to the committed bits
(``tests/golden/digests.py``). A failure names the controller and the cells whose bits moved; a
change meant to move them is a numerics epoch (docs/numerics.md), which rewrites the files."""

from __future__ import annotations

import json

import pytest

from scftc_cli.registry import registry
from scftc_cli.versions import published_names
from tests.golden.digests import N_FAULTS, N_SEEDS, cells_of, controller_digests, golden_path

CASES = [(version, name) for version in published_names() for name in registry(version)]


def _committed(version: str) -> dict:
    return json.loads(golden_path(version).read_text())


@pytest.mark.parametrize("version", published_names())
def test_every_builtin_and_cell_has_a_committed_digest(version):
    document = _committed(version)
    assert document["episodes"] == {"n_faults": N_FAULTS, "n_seeds": N_SEEDS, "draw": "public"}
    labels = {f"{c.split}/{c.label}" for c in cells_of(version)}
    assert set(document["digests"]) == set(registry(version)), "a built-in without a golden digest"
    for name, cells in document["digests"].items():
        assert set(cells) == labels, f"{name}: the golden cells are not the version's cells"


@pytest.mark.parametrize(("version", "name"), CASES, ids=[f"{v}:{n}" for v, n in CASES])
def test_builtin_flies_its_golden_bits(version, name):
    committed = _committed(version)["digests"][name]
    flown = controller_digests(version, name)
    moved = sorted(cell for cell in committed if flown.get(cell) != committed[cell])
    assert not moved, (
        f"{name} on {version}: the bits of {len(moved)} cells moved ({', '.join(moved[:6])}...); "
        "if that is meant, it is a numerics epoch (docs/numerics.md)"
    )
