"""``fdir``'s detection delay and false alarms in the ``scftc-v2`` study: measured on the battery's own
held-out actuator episodes, drawn as the ``fdir_detection`` figure and written as
``fdir_detection.md``; a class nothing was detected in still renders."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from scftc_cli.evaluate import Cell, CellRun
from scftc_cli.protocol import Progress
from scftc_cli.registry import registry
from scftc_cli.study import run as study_run
from scftc_cli.study.figures import fdir_detection as detection_figure
from scftc_cli.study.figures import save, write_figures
from scftc_cli.study.run import (
    Detection,
    fdir_detection,
    measures_detection,
    planned_steps,
    run_study,
)
from scftc_cli.study.tables import detection_markdown, detection_rows, write_tables
from scftc_cli.versions import get_version
from scftc_cli.versions.v1.spec import V1
from scftc_cli.versions.v2.spec import V2

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
DETECTOR = get_version(V2.version).study.detector or ""


def _redrawn_run(fault_class: str) -> CellRun:
    """A held-out actuator cell as a cluster run leaves it: no episodes, drawn again on demand."""
    cell = Cell("test", fault_class, None)
    return CellRun(cell, None, None, None, draw=(V2.version, 1, 1, b""))  # type: ignore[arg-type]


def _rows_by_class(table: str) -> dict[str, list[str]]:
    rows = [line.strip("|").split("|") for line in table.splitlines() if line.startswith("| ")]
    return {cells[0].strip(): [c.strip() for c in cells[1:]] for cells in rows[1:]}


def test_held_out_detection_is_drawn_and_tabled_for_every_actuator_class(tmp_path: Path) -> None:
    entry = registry(V2.version)[DETECTOR]
    runs = [_redrawn_run(c) for c in V2.fault_classes]
    runs.append(CellRun(Cell("test", "sign", "st_bias"), None, None, None))  # type: ignore[arg-type]
    detections = fdir_detection(entry, V2, runs)
    assert [d.fault_class for d in detections] == list(V2.fault_classes)  # sensor cells left out
    for d in detections:
        assert d.delay_steps.shape == d.faulted.shape == d.pre_onset_steps.shape == (1,)
        assert d.dt_s == V2.dt_s and d.pre_onset_steps[0] > 0

    paths = save(detection_figure(detections), tmp_path, "fdir_detection")
    assert [p.name for p in paths] == ["fdir_detection.png", "fdir_detection.svg"]
    assert paths[0].read_bytes()[:8] == PNG_SIGNATURE and paths[0].stat().st_size > 20_000
    assert "held-out split" in paths[1].read_text()

    table = detection_markdown(V2, detections)
    rows = _rows_by_class(table)
    assert list(rows) == list(V2.fault_classes)
    for d in detections:
        assert rows[d.fault_class][0] == f"{int(d.detected.sum())}/{d.n_faulted}"


def _detection(fault_class: str, delay_steps: list[int], faulted: list[bool], **alarms: int) -> Detection:
    n = len(delay_steps)
    return Detection(
        fault_class=fault_class,
        delay_steps=np.array(delay_steps),
        faulted=np.array(faulted),
        pre_onset_alarms=np.full(n, alarms.get("pre", 0)),
        pre_onset_steps=np.full(n, 400),
        healthy_alarms=np.full(n, alarms.get("healthy", 0)),
        healthy_wheel_steps=np.full(n, alarms.get("healthy_steps", 0)),
        dt_s=0.5,
    )


def test_a_class_never_detected_renders_in_the_table_and_the_figure(tmp_path: Path) -> None:
    detections = [
        _detection("sign", [1, 1, 2, 3, 40], [True] * 5, healthy=2, healthy_steps=1995),
        _detection("gain", [-1, -1, -1], [True] * 3),  # faulted, never detected
        _detection("healthy", [-1, -1], [False, False], pre=1),  # no faulted episode at all
    ]
    never, healthy = detections[1], detections[2]
    assert detections[0].delay_summary() == (2, 40, 40)
    assert never.delay_summary() is None and never.n_missed == 3 and never.delays.size == 0
    assert healthy.n_faulted == 0 and healthy.n_missed == 0

    rows = {r[0]: r[1:] for r in detection_rows(detections)}
    assert rows["sign"] == ["5/5", "2 / 40 / 40", "0 / 2000", "10 / 9975"]
    assert rows["gain"] == ["0/3", "- / - / -", "0 / 1200", "0 / 0"]
    assert rows["healthy"] == ["0/0", "- / - / -", "2 / 800", "0 / 0"]
    assert list(_rows_by_class(detection_markdown(V2, detections))) == ["sign", "gain", "healthy"]

    fig = detection_figure(detections)
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend[1] == "gain: 0/3 detected, 3 never detected"
    assert legend[2] == "healthy: no faulted episode"
    paths = save(fig, tmp_path, "fdir_detection")
    assert all(p.stat().st_size > 0 for p in paths)


def test_no_false_alarm_anywhere_is_said_on_the_figure(tmp_path: Path) -> None:
    fig = detection_figure([_detection("loss", [1, 2], [True, True])])
    assert "no false alarm in any class" in [t.get_text() for t in fig.axes[1].texts]
    save(fig, tmp_path, "fdir_detection")


def test_only_versions_with_onsets_and_fdir_measure_detection() -> None:
    assert measures_detection(V2, registry(V2.version))
    assert not measures_detection(V1, registry(V1.version))
    without = {k: v for k, v in registry(V2.version).items() if k != DETECTOR}
    assert not measures_detection(V2, without)
    battery = len(V2.fault_classes) + len(V2.sensor_faults)  # its cells (its trajectory: read off them)
    assert planned_steps(V2) - planned_steps(V2, without) == battery * V2.steps  # no detection flight


class _Counting(Progress):
    def __init__(self) -> None:
        self.steps = 0.0

    def advance(self, amount: float = 1.0) -> None:
        self.steps += amount


@pytest.mark.slow
def test_the_study_writes_the_detection_figure_and_table(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    only_fdir = {DETECTOR: registry(V2.version)[DETECTOR]}
    monkeypatch.setattr(study_run, "registry", lambda _benchmark=None: only_fdir)
    progress = _Counting()
    study = run_study(V2, 1, 1, progress=progress)
    assert progress.steps == planned_steps(V2, only_fdir)
    assert [d.fault_class for d in study.detection] == list(V2.fault_classes)
    names = {p.name for p in write_tables(study, tmp_path) + write_figures(study, tmp_path)}
    assert {"fdir_detection.md", "fdir_detection.png", "fdir_detection.svg"} <= names
    assert list(_rows_by_class((tmp_path / "fdir_detection.md").read_text())) == list(V2.fault_classes)


@pytest.mark.slow
def test_the_detector_read_off_the_battery_flight_is_the_detector_flown_again(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The study measures the detector on its battery flight (stacked with the sensor cells); a
    flight of the actuator cells alone measures the same, number for number."""
    only_fdir = {DETECTOR: registry(V2.version)[DETECTOR]}
    monkeypatch.setattr(study_run, "registry", lambda _benchmark=None: only_fdir)
    study = run_study(V2, 1, 3)
    again = fdir_detection(only_fdir[DETECTOR], V2, study.runs[DETECTOR])
    assert [d.fault_class for d in again] == [d.fault_class for d in study.detection]
    for read, flown in zip(study.detection, again, strict=True):
        for name in ("delay_steps", "faulted", "pre_onset_alarms", "healthy_alarms", "healthy_wheel_steps"):
            np.testing.assert_array_equal(getattr(read, name), getattr(flown, name), err_msg=name)
    assert sum(d.n_faulted for d in again) > 0  # something to detect
