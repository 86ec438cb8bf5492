"""The diagnosis ranking (``board/diagnosis.py``) under the ``faulted_unit`` rule: five probes
that read nothing from the flight (``probes.py``) never rank above an honest detector, flown
through the normal evaluate path on a few small cells; and the ranking's tie groups, budget and
renderings on a hand-made board.

``VERSION`` is the version flown: ``scftc-v4``, the first that ranks its diagnosis, against its own
honest detector (its composed ``fdir``); ``ranked_spec`` (the diagnosis ranked under the
``faulted_unit`` rule) is a no-op on it and lets the tests fly an older version. The cells are
``SPLIT``'s: v4's held-out split (a draft's train split: no deployable controller flies a draft's
held-out split).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator

import numpy as np
import pytest

from scftc_cli.board.diagnosis import rank_diagnosis
from scftc_cli.board.html import board_html
from scftc_cli.board.models import Entry, Leaderboard, empty_board
from scftc_cli.board.ranking import rank_board
from scftc_cli.board.render import board_csv, board_json, board_markdown
from scftc_cli.evaluate import Cell, board_cells, evaluate_cells
from scftc_cli.records import CellResult, DiagnosisByFault, DiagnosisStats, FinalError
from scftc_cli.registry import make_controller
from scftc_cli.scoring import gate_stat
from scftc_cli.sim import testbed as sim_testbed
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.statistics import profile_counts
from scftc_cli.versions import get_spec, get_version, register, unregister

from .probes import FixedFrom, probes
from .test_board import round_one
from .test_diagnosis import sealed_entry

VERSION = "scftc-v4"
"""The version flown (see the module docstring)."""
SPLIT = "test" if not get_version(VERSION).draft else "train"
"""The split flown (see the module docstring)."""
HONEST = "fdir"
"""The built-in honest detector of ``VERSION``: its health reports come from residual tests."""
CLASSES = ("nominal", "gain", "loss")
"""Classes flown: the nominal class (healthy flight only) and two wheel faults."""
N_FAULTS, N_SEEDS = 2, 2


def ranked_spec(version: str = VERSION) -> BenchmarkSpec:
    """``version``'s spec with its diagnosis ranked under the ``faulted_unit`` rule."""
    spec = get_spec(version)
    assert spec.diagnosis is not None
    rule = spec.diagnosis.model_copy(update={"ranked": True, "detection": "faulted_unit"})
    return spec.model_copy(update={"diagnosis": rule})


@pytest.fixture(scope="module")
def flown() -> dict[str, list[CellResult]]:
    """Every probe's and the honest detector's cells, flown on ``CLASSES`` of ``SPLIT``."""
    spec = ranked_spec()
    cells = [Cell(SPLIT, c) for c in CLASSES]
    controllers = {HONEST: make_controller(HONEST, VERSION), **probes(spec, CLASSES)}
    return {
        name: [
            run.result
            for run in evaluate_cells(lambda _c, c=c: c, spec, cells, n_faults=N_FAULTS, n_seeds=N_SEEDS)
        ]
        for name, c in controllers.items()
    }


def test_no_probe_ranks_on_diagnosis_above_the_honest_detector(flown):
    spec = ranked_spec()
    assert spec.diagnosis is not None
    standings = rank_diagnosis(list(flown.items()), CLASSES, spec.diagnosis.false_alarm_budget)
    ranked = [r.name for r in standings.ranked]
    assert ranked[0] == HONEST, standings
    honest = standings.ranked[0]
    assert honest.rank == 1 and honest.pool.isolated.rate > 0
    assert standings.silent == ["silent"]  # reports nothing: not listed, not flagged
    assert all(r.name != "silent" for r in [*standings.ranked, *standings.unranked])
    for r in [*standings.ranked[1:], *standings.unranked]:
        assert r.rank is None or r.rank >= honest.rank, r
        assert r.rank is None or r.pool.isolated.rate < honest.pool.isolated.rate, r
    # an alarm raised from step 0 is a false alarm in every healthy episode: over the budget
    over = {r.name: r.reason for r in standings.unranked}
    assert {"all_failed", "common_from_0"} <= set(over)
    assert "over the false-alarm budget" in over["all_failed"]


def test_every_unit_failed_is_a_false_isolation_in_every_episode_but_still_detects(flown):
    (pool,) = [r.pool for r in rank_diagnosis([("all_failed", flown["all_failed"])], CLASSES, 1.0).ranked]
    # it names the faulted units too, so it detects (delay 0: its alarm is on at the onset) ...
    assert pool.detected.rate == 1.0 and pool.mean_delay_s == 0.0
    # ... but names every healthy unit as well: a false isolation everywhere, and never isolates
    assert pool.false_isolation_episodes == pool.episodes and pool.isolated.k == 0
    assert pool.false_alarms.rate == 1.0


def test_the_v3_rule_would_credit_a_constant_alarm():
    """What the ``faulted_unit`` rule fixes: under ``any_alarm`` (v3's) an alarm raised at step 0
    on units no fault touched detects every fault with no delay; under ``faulted_unit`` it detects
    none, and is a false isolation in every episode."""
    spec = get_spec(VERSION)
    assert spec.diagnosis is not None
    bed = sim_testbed.testbed(VERSION)
    truth = bed.diagnosis_truth(bed.draw(SPLIT, "loss", None, 2, 1))
    wrong = (truth.codes.max(axis=0) == 0).astype(np.int64)  # every unit these faults leave healthy
    assert wrong.any()
    cells = [Cell(SPLIT, "loss")]
    v3_rule = spec.diagnosis.model_copy(update={"detection": "any_alarm", "ranked": False})
    results = {
        rule.diagnosis.detection: evaluate_cells(
            lambda _c: FixedFrom(spec.action_dim, wrong, 0), rule, cells, n_faults=2, n_seeds=1
        )[0].result.diagnosis
        for rule in (spec.model_copy(update={"diagnosis": v3_rule}), ranked_spec())
        if rule.diagnosis is not None
    }
    old, new = results["any_alarm"], results["faulted_unit"]
    assert old is not None and new is not None and old.faulted == new.faulted == 2
    assert old.detected == 2 and old.delay_mean_s == 0.0 and old.false_isolation_episodes is None
    assert new.detected == 0 and new.delay_mean_s is None and new.false_isolation_episodes == 2
    assert new.false_alarm_episodes == old.false_alarm_episodes == 2  # false alarms are counted alike
    assert new.by_fault is not None and new.by_fault.false_isolation_episodes == [1, 1]


# a hand-made board of a version that ranks its diagnosis

RANKED = "toy-ranked-diagnosis"


@pytest.fixture(scope="module")
def ranked_version() -> Iterator[BenchmarkSpec]:
    spec = ranked_spec().model_copy(update={"version": RANKED})
    register(RANKED, dataclasses.replace(get_version(VERSION), spec=spec))
    try:
        yield spec
    finally:
        unregister(RANKED)


def _diagnosis(spec: BenchmarkSpec, faulted: bool, isolated: int, severity: int, alarms: int, reported: bool):
    """A cell's diagnosis: per fault, ``isolated`` and ``severity`` of its seeds (faulted cells),
    ``alarms`` false-alarm episodes; detection of every faulted episode, 20 s late."""
    faults, seeds = spec.n_faults, spec.n_seeds
    per = {
        "faulted": [seeds if faulted else 0] * faults,
        "detected": [seeds if faulted and reported else 0] * faults,
        "isolated": [isolated if faulted else 0] * faults,
        "severity_right": [severity if faulted else 0] * faults,
        "healthy_episodes": [seeds] * faults,
        "false_alarm_episodes": [alarms] * faults,
        "false_isolation_episodes": [alarms] * faults,
    }
    total = {k: sum(v) for k, v in per.items()}
    return DiagnosisStats(
        faulted=total["faulted"],
        detected=total["detected"],
        delay_mean_s=20.0 if total["detected"] else None,
        delay_median_s=20.0 if total["detected"] else None,
        isolated=total["isolated"],
        severity_right=total["severity_right"],
        healthy_episodes=total["healthy_episodes"],
        false_alarm_episodes=total["false_alarm_episodes"],
        healthy_hours=faults * seeds * 0.2,
        false_alarms=total["false_alarm_episodes"],
        reported=reported,
        false_isolation_episodes=total["false_isolation_episodes"],
        by_fault=DiagnosisByFault(**per),
    )


def _entry(
    spec: BenchmarkSpec,
    name: str,
    isolated: int,
    severity: int = 0,
    alarms: int = 0,
    reported: bool = True,
    privileged: bool = False,
) -> Entry:
    n = spec.episodes_per_cell
    passed = np.arange(n) < n // 2
    stat = gate_stat(passed, fault_index=np.arange(n) // spec.n_seeds)
    final = np.where(passed, 0.1, 10.0)
    cells = [
        CellResult(
            split="test",
            fault_class=c.fault_class,
            sensor=c.sensor,
            n=n,
            settled=stat,
            operational=stat,
            touch_once=stat,
            final_error_deg=FinalError(median=1.0, mean=5.0, profile=profile_counts(final).tolist()),
            window_settled=[n // 2] * 3,
            diagnosis=_diagnosis(
                spec, c.fault_class != "nominal" or c.sensor is not None, isolated, severity, alarms, reported
            ),
        )
        for c in board_cells(spec)
    ]
    return sealed_entry(name, spec, cells, privileged)


@pytest.fixture(scope="module")
def ranked_board(ranked_version: BenchmarkSpec) -> Leaderboard:
    spec = ranked_version
    entries = [
        _entry(spec, "sharp", isolated=9, severity=8),
        _entry(spec, "sharp_twin", isolated=9, severity=5),  # same isolation: tied with sharp
        _entry(spec, "blunt", isolated=2, severity=2),  # separated from both
        _entry(spec, "noisy", isolated=10, severity=10, alarms=1),  # 10 % false alarms: over the budget
        _entry(spec, "mute", isolated=0, reported=False),  # reports nothing: not listed
        _entry(spec, "oracle", isolated=10, severity=10, privileged=True),  # told the fault: not ranked
    ]
    return empty_board(spec.version).model_copy(update={"rounds": [round_one()], "entries": entries})


def test_the_diagnosis_ranking_groups_ties_and_lists_the_noisy_apart(ranked_board):
    standings = rank_board(ranked_board).diagnosis
    assert standings is not None
    assert [(r.name, r.rank, r.tied) for r in standings.ranked] == [
        ("sharp", 1, True),  # not separated on isolation: one group, ordered by severity
        ("sharp_twin", 1, True),
        ("blunt", 3, False),
    ]
    (noisy,) = standings.unranked
    assert noisy.name == "noisy" and noisy.rank is None and "over the false-alarm budget" in noisy.reason
    assert standings.silent == ["mute"]
    sharp = standings.ranked[0].pool
    low, high = sharp.isolated.interval_by_fault
    assert sharp.isolated.rate == pytest.approx(0.9) and low <= 0.9 <= high
    assert sharp.false_alarms.k == 0 and sharp.mean_delay_s == pytest.approx(20.0)


def test_the_renderings_show_the_diagnosis_ranking(ranked_board):
    text = board_markdown(ranked_board)
    assert "## Diagnosis ranking" in text and "**Rule:** sealed deployable entries that report" in text
    section = text.split("## Diagnosis ranking", 1)[1]
    assert "| 1= | `sharp`" in section and "| 3 | `blunt`" in section
    assert "| - | `noisy`" in section and "Not listed (they report no diagnosis): `mute`" in section
    assert "`oracle`" not in section.split("\n## ", 1)[0]
    doc = json.loads(board_json(ranked_board))["standings"]["diagnosis"]
    assert [r["name"] for r in doc["ranked"]] == ["sharp", "sharp_twin", "blunt"]
    assert doc["unranked"][0]["name"] == "noisy" and doc["not_listed"] == ["mute"]
    assert doc["ranked"][0]["isolated"]["rate"] == pytest.approx(0.9)
    html = board_html([ranked_board])
    assert f'id="{RANKED}-diagnosis-ranking"' in html and "Diagnosis ranking" in html
    header = board_csv(ranked_board).splitlines()[0]
    assert "diagnosis_false_isolation_episodes" in header and "diagnosis_by_fault" not in header


def test_a_version_that_does_not_rank_its_diagnosis_renders_as_before():
    from scftc_cli.board.store import default_board_path, read_board

    board = read_board(default_board_path("scftc-v3"), "scftc-v3")
    assert rank_board(board).diagnosis is None
    assert "Diagnosis ranking" not in board_markdown(board)
    assert "diagnosis" not in json.loads(board_json(board))["standings"]
    assert "diagnosis_false_isolation_episodes" not in board_csv(board).splitlines()[0]
