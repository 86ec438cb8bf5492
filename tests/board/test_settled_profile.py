"""The ranked gate's profile on a board (``CellResult.settled_profile``): records written before it
existed (every published v1-v3 entry) still load, render and compare unchanged, and say the profile
is unavailable; a record that holds one is checked against its own gates and drawn with its bands."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from scftc_cli.board import store
from scftc_cli.board.html import board_html
from scftc_cli.board.models import Entry, check_cell
from scftc_cli.board.ranking import pooled_settled, pooled_settled_profile_of, rank_board
from scftc_cli.board.render import board_markdown
from scftc_cli.board.verify import compare_cells
from scftc_cli.records import SettledProfile
from scftc_cli.scoring import settled_profile, settled_profile_taus
from scftc_cli.versions import published_names
from scftc_cli.versions.v1.spec import V1
from tests.board.test_board import board_of, cell, entry, ks

ROOT = Path(__file__).resolve().parents[2]
TAUS = settled_profile_taus(V1.gates)


def profiled_cell(fault_class: str, sensor: str | None, k: int):
    """``test_board.cell`` with the ranked gate's profile its episodes give: the ``k`` settled ones
    hold within 0.1 deg over the dwell, the others at 10 deg (outside the settled and operational
    tolerances alike, as the hand-made cell's gates say)."""
    base = cell(fault_class, sensor, k)
    worst = np.where(np.arange(base.n) < k, 0.1, 10.0)
    profile = settled_profile(worst, TAUS, np.arange(base.n) % V1.n_faults)
    return base.model_copy(update={"settled_profile": profile})


def profiled_entry(name: str, counts: dict[str, int]) -> Entry:
    plain = entry(name, counts)
    data = plain.model_dump(by_alias=True)
    for draw in ("public", "sealed"):
        data[draw] = [
            profiled_cell(c.fault_class, c.sensor, c.settled.k).model_dump(by_alias=True)
            for c in getattr(plain, draw)
        ]
    return Entry.model_validate(data)


SEALED_BEFORE_PROFILES = ("scftc-v1", "scftc-v2", "scftc-v3")
"""The published boards sealed before ``SettledProfile`` existed; later boards hold it in every cell."""


@pytest.mark.parametrize("version", published_names())
def test_published_boards_load_and_render_with_or_without_settled_profiles(version: str):
    path = ROOT / "leaderboard" / f"{version}.json"
    board = store.read_board(path, version)
    cells = [c for e in board.entries for c in (*e.public, *e.sealed)]
    before = version in SEALED_BEFORE_PROFILES
    assert cells and all((c.settled_profile is None) == before for c in cells)
    stored = json.loads(path.read_text())["entries"]
    for e, written in zip(board.entries, stored, strict=True):  # nothing added, no stored number moves
        for draw in ("public", "sealed"):
            assert [c.model_dump(mode="json", by_alias=True) for c in getattr(e, draw)] == written[draw]
    assert board_markdown(board)
    page = board_html([board])
    assert f'id="{version}-profile-chart"' in page
    if before:
        assert "settled-gate profile is unavailable" in page  # said, not drawn from nothing
        assert "not the settled rate" in page  # the final-error profile stands in, labelled
    else:
        assert "settled-gate profile is unavailable" not in page  # the ranked gate's profile is drawn


def test_an_old_record_compares_clean_against_a_rerun_that_has_a_profile():
    old, new = cell("gain", None, 300), profiled_cell("gain", None, 300)
    assert compare_cells([old], [new]) == []
    moved = new.model_copy(
        update={"settled_profile": SettledProfile(k=[0] * (len(TAUS) - 1) + [new.n])}  # gates alike
    )
    assert compare_cells([new], [moved]) == [f"{new.label} settled profile differs from the re-run's"]


def test_a_settled_profile_must_read_its_own_gates():
    good = profiled_cell("gain", None, 300)
    check_cell(good, V1.n_faults, V1.n_seeds, "here", V1.gates)
    profile = good.settled_profile
    assert profile is not None
    i = int(np.flatnonzero(TAUS == V1.gates.settled_deg)[0])
    off = SettledProfile(k=[k + 1 if j >= i and k == 300 else k for j, k in enumerate(profile.k)])
    with pytest.raises(ValueError, match="settled_profile reads 301 at 0.2 deg, settled k = 300"):
        check_cell(
            good.model_copy(update={"settled_profile": off}), V1.n_faults, V1.n_seeds, "here", V1.gates
        )
    with pytest.raises(ValueError, match="must hold 42 counts"):
        short = SettledProfile(k=profile.k[:-1])
        check_cell(good.model_copy(update={"settled_profile": short}), V1.n_faults, V1.n_seeds, "x", V1.gates)
    with pytest.raises(ValueError, match="non-decreasing"):
        SettledProfile(k=[3, 2])


def test_the_board_draws_the_ranked_gate_profile_with_its_bands():
    board = board_of([profiled_entry("alpha", ks(500, 400, 120)), profiled_entry("beta", ks(450, 300, 60))])
    ranking = rank_board(board)
    page = board_html([board])
    assert "settled-gate profile is unavailable" not in page
    assert "largest error over every window&#x27;s final dwell" in page  # the honest axis
    assert page.count('class="gate-interval"') >= 2 and 'class="band"' in page  # main chart, details
    for r in ranking.deployable:
        values = pooled_settled_profile_of(r.entry.sealed, ranking.ranked_classes)
        assert values is not None
        i = int(np.flatnonzero(TAUS == V1.gates.settled_deg)[0])
        assert values[i] == pytest.approx(pooled_settled(r.entry.sealed, ranking.ranked_classes).rate)
        assert f"{100 * values[i]:.1f} %</span>" in page
