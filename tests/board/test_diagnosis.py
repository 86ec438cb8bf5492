"""The board of a version that scores a diagnosis (scftc-v3): each entry's false alarms,
detection, isolation and delay pooled over its sealed cells and shown beside its settled rate; an
entry over the false-alarm budget is flagged and still ranked on its settled rate; the rule says
so. Versions without a diagnosis render as before."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest

from scftc_cli.board.html import board_html
from scftc_cli.board.models import Entry, Leaderboard, empty_board
from scftc_cli.board.ranking import pooled_diagnosis, rank_board
from scftc_cli.board.render import board_csv, board_json, board_markdown
from scftc_cli.evaluate import board_cells
from scftc_cli.records import CellResult, DiagnosisStats, FinalError
from scftc_cli.scoring import gate_stat
from scftc_cli.statistics import profile_counts
from scftc_cli.versions.v3.spec import V3

from .test_board import SALT, round_one

N = V3.episodes_per_cell
BUDGET = V3.diagnosis.false_alarm_budget if V3.diagnosis is not None else 0.0


def cell(
    fault_class: str, sensor: str | None, k: int, false_alarm_episodes: int, detected: int
) -> CellResult:
    passed = np.arange(N) < k
    stat = gate_stat(passed, fault_index=np.arange(N) % V3.n_faults)
    final = np.where(passed, 0.1, 10.0)
    faulted = 0 if fault_class == "nominal" and sensor is None else N
    return CellResult(
        split="test",
        fault_class=fault_class,
        sensor=sensor,
        n=N,
        settled=stat,
        operational=stat,
        touch_once=stat,
        final_error_deg=FinalError(
            median=float(np.median(final)), mean=float(np.mean(final)), profile=profile_counts(final).tolist()
        ),
        window_settled=[k, k, k],
        diagnosis=DiagnosisStats(
            faulted=faulted,
            detected=min(detected, faulted),
            delay_mean_s=20.0 if min(detected, faulted) else None,
            isolated=min(detected, faulted) // 2,
            severity_right=min(detected, faulted) // 4,
            healthy_episodes=N,
            false_alarm_episodes=false_alarm_episodes,
            healthy_hours=N * 0.2,
            false_alarms=false_alarm_episodes,
        ),
    )


def sealed_entry(name: str, spec, cells: list, privileged: bool = False) -> Entry:
    """A hand-made built-in sealed in round 1 with ``cells`` as both its draws."""
    return Entry(
        name=name,
        kind="builtin",
        privileged=privileged,
        summary="hand-made",
        benchmark_version=spec.version,
        package_version="0",
        created_utc="2026-01-01T00:00:00Z",
        n_faults=spec.n_faults,
        n_seeds=spec.n_seeds,
        status="sealed",
        round=1,
        added_board_version=2,
        public=cells,
        sealed=cells,
        sealed_salt=SALT,
    )


def entry(name: str, k: int, false_alarm_episodes: int, detected: int, privileged: bool = False) -> Entry:
    cells = [cell(c.fault_class, c.sensor, k, false_alarm_episodes, detected) for c in board_cells(V3)]
    return sealed_entry(name, V3, cells, privileged)


def board(entries: list[Entry]) -> Leaderboard:
    return empty_board(V3.version).model_copy(update={"rounds": [round_one()], "entries": entries})


@pytest.fixture
def v3_board() -> Leaderboard:
    # 'loud' settles most but alarms in 2 % of healthy episodes (over the 1 % budget); 'quiet'
    # alarms in 0.4 %; 'silent' reports nothing (never alarms, never detects)
    return board(
        [
            entry("loud", 490, false_alarm_episodes=10, detected=500),
            entry("quiet", 450, false_alarm_episodes=2, detected=400),
            entry("silent", 300, false_alarm_episodes=0, detected=0),
            entry("oracle", 500, false_alarm_episodes=0, detected=500, privileged=True),
        ]
    )


def test_the_pooled_diagnosis_adds_every_sealed_cells_counts():
    e = entry("probe", 400, false_alarm_episodes=3, detected=100)
    d = pooled_diagnosis(e.sealed)
    cells, actuator = len(board_cells(V3)), len(V3.fault_classes)
    assert d is not None and cells > actuator
    # false alarms on the actuator cells only: a sensor cell flies its base cell's healthy stretch again
    assert d.healthy_episodes == actuator * N and d.false_alarm_episodes == 3 * actuator
    assert d.false_alarm_rate == pytest.approx(3 / N)
    assert d.faulted == (cells - 1) * N and d.detected == 100 * (cells - 1)  # nominal has no fault
    assert d.mean_delay_s == pytest.approx(20.0)
    assert d.false_alarms_per_hour == pytest.approx(3 / (N * 0.2))
    low, high = d.false_alarm_interval
    assert low < d.false_alarm_rate < high


def test_an_entry_over_the_budget_is_flagged_and_still_ranked_on_its_settled_rate(v3_board):
    ranking = rank_board(v3_board)
    names = [r.entry.name for r in ranking.deployable]
    assert names == ["loud", "quiet", "silent"]  # settled rate decides, alarms do not
    over = {r.entry.name: r.over_budget for r in ranking.deployable}
    assert over == {"loud": True, "quiet": False, "silent": False}
    assert ranking.deployable[0].rank == 1
    assert f"more than {100 * BUDGET:g} %" in ranking.rule
    assert "still ranks on its settled rate" in ranking.rule


def test_the_renderings_show_the_diagnosis_beside_the_settled_rate_and_the_flag(v3_board):
    text = board_markdown(v3_board)
    assert "## Diagnosis" in text and f"false-alarm budget {100 * BUDGET:g} %" in text
    loud = next(line for line in text.splitlines() if line.startswith("| `loud`") and "/ " in line)
    assert "**yes**" in loud and "98.0" in loud  # its settled rate beside its alarms
    assert "over the false-alarm budget" in text and "## Flagged" in text
    doc = json.loads(board_json(v3_board))
    rows = {r["name"]: r for r in doc["standings"]["deployable"]}
    assert rows["loud"]["over_false_alarm_budget"] is True
    assert rows["quiet"]["diagnosis"]["false_alarm_episodes"] == 2 * len(V3.fault_classes)
    table = list(csv.DictReader(io.StringIO(board_csv(v3_board))))
    assert {r["diagnosis_false_alarm_episodes"] for r in table if r["name"] == "loud"} == {"10"}
    assert {r["over_false_alarm_budget"] for r in table if r["name"] == "loud"} == {"True"}
    html = board_html([v3_board])
    assert 'id="scftc-v3-diagnosis-table"' in html and "over the false-alarm budget" in html


def test_a_version_without_a_diagnosis_keeps_its_rule_and_tables():

    from scftc_cli.board.store import default_board_path, read_board

    for version in ("scftc-v1", "scftc-v2"):  # the committed boards' stored rule is what a new board gets
        committed = read_board(default_board_path(version), version)
        assert committed.ranking == empty_board(version).ranking
        assert "false alarm" not in committed.ranking
    v1 = Leaderboard(rounds=[round_one()], entries=[])
    assert "## Diagnosis" not in board_markdown(v1)
    assert "diagnosis" not in board_csv(v1).splitlines()[0]
