"""``diagnosis.md``: a version that scores a diagnosis gets a table of what each controller's fault
detection said, pooled as the board pools an entry's cells."""

from __future__ import annotations

import pytest

from scftc_cli.board.ranking import pooled_diagnosis
from scftc_cli.evaluate import Cell, eval_result, evaluate_cells
from scftc_cli.registry import make_controller
from scftc_cli.study.run import BatteryReport, SensorReport, Study
from scftc_cli.study.tables import diagnosis_markdown
from scftc_cli.versions.v3.spec import V3

CELLS = [Cell("test", "nominal"), Cell("test", "sign", "st_stuck")]  # healthy flight; a faulted head


@pytest.fixture(scope="module")
def table() -> tuple[str, dict]:
    results = {}
    for name in ("pd", "fdir"):
        runs = evaluate_cells(
            lambda _c, name=name: make_controller(name, V3.version), V3, CELLS, n_faults=2, n_seeds=1
        )
        results[name] = eval_result(name, False, V3, runs)
    battery = BatteryReport(
        benchmark_version=V3.version, n_faults=2, n_seeds=1, results=list(results.values())
    )
    sensor = SensorReport.model_construct()  # the table reads the battery only
    study = Study(spec=V3, battery=battery, sensor=sensor, trajectories=[], runs={})
    return diagnosis_markdown(study), results


def _rows(text: str, section: str) -> dict[str, list[str]]:
    part = text.split(section, 1)[1].split("\n## ", 1)[0]
    lines = [ln for ln in part.splitlines() if ln.startswith("| ") and not ln.startswith("| controller")]
    return {cells[0]: cells[1:] for cells in ([c.strip() for c in ln.strip("|").split("|")] for ln in lines)}


def test_the_pooled_row_is_the_boards_pooled_diagnosis(table) -> None:
    text, results = table
    rows = _rows(text, "## Pooled over every cell")
    assert set(rows) == {"pd", "fdir"}
    for name, result in results.items():
        d = pooled_diagnosis(result.cells)
        assert d is not None
        assert rows[name][0].startswith(f"{d.false_alarm_episodes} / {d.healthy_episodes}:")
        assert rows[name][2].startswith(f"{d.detected} / {d.faulted}")
    assert rows["pd"][2].startswith("0 / ")  # pd reports nothing: it never detects


def test_detection_per_class_covers_the_sensor_cells_and_false_alarms_the_actuator_cells_only(table) -> None:
    text, results = table
    detected = _rows(text, "## Detected")
    alarms = _rows(text, "## False-alarm episodes")
    header = [ln for ln in text.split("## Detected", 1)[1].splitlines() if ln.startswith("| controller")][0]
    assert "st_stuck" in header and "nominal" in header
    header = [
        ln for ln in text.split("## False-alarm episodes", 1)[1].splitlines() if ln.startswith("| controller")
    ][0]
    assert "st_stuck" not in header
    nominal = next(c for c in results["fdir"].cells if c.fault_class == "nominal" and c.sensor is None)
    assert nominal.diagnosis is not None
    assert (
        alarms["fdir"][0]
        == f"{nominal.diagnosis.false_alarm_episodes} / {nominal.diagnosis.healthy_episodes}"
    )
    assert detected["fdir"][0] == "-"  # a nominal cell has no faulted episode
