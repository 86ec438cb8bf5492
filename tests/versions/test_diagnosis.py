"""What ``scftc-v3`` adds to the framework, proved on ``toy-d0`` (the toy axis with two pointing
windows and a scored diagnosis): the settled gate holds every window's final dwell, each window's
settled count is reported, and a controller's health reports are scored (detection delay, false
alarms, isolation, severity) the same way in process and through the real sandbox."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.evaluate import Cell, evaluate_cells
from scftc_cli.records import EpisodeDiagnosis
from scftc_cli.scoring import diagnosis_stats
from scftc_cli.versions import get_spec, register, unregister
from tests.sandbox import needs_sandbox
from tests.toy_version.diagnosed import NAME, Oracle

runner = CliRunner()


@pytest.fixture
def toy() -> Iterator[str]:
    register(NAME, "tests.toy_version.diagnosed:VERSION")
    try:
        yield NAME
    finally:
        unregister(NAME)


def _cell(*args: str) -> dict:
    result = runner.invoke(app, ["eval", "--benchmark", NAME, *args, "--format", "json"])
    assert result.exit_code == 0, result.output
    (cell,) = json.loads(result.stdout)["cells"]
    return cell


def test_every_window_is_scored_and_a_perfect_diagnosis_scores_perfectly(toy: str) -> None:
    cell = _cell("--controller", "oracle")
    n = cell["n"]
    assert cell["window_settled"] == [n, n] and cell["settled"]["k"] == n  # both targets held
    d = cell["diagnosis"]
    assert (d["faulted"], d["detected"], d["isolated"], d["severity_right"]) == (n, n, n, n)
    assert d["delay_mean_s"] == 0.0 and d["false_alarm_episodes"] == 0 and d["false_alarms"] == 0
    assert d["healthy_episodes"] == n and d["healthy_hours"] > 0


def test_a_controller_that_reports_nothing_never_alarms(toy: str) -> None:
    d = _cell("--controller", "tracker")["diagnosis"]
    assert d["detected"] == 0 and d["false_alarm_episodes"] == 0 and d["isolated"] == 0
    assert d["delay_mean_s"] is None


def test_the_settled_gate_needs_every_window(toy: str) -> None:
    class FirstWindowOnly(Oracle):
        """Holds the first target and ignores the second."""

        def act(self, obs: np.ndarray) -> np.ndarray:
            self.k = min(self.k, get_spec(NAME).steps // 2 - 1)
            return super().act(obs)

    (run,) = evaluate_cells(lambda _c: FirstWindowOnly(), get_spec(NAME), [Cell("test", "flip")])
    first, second = run.result.window_settled or [0, 0]
    assert first == run.result.n and second == 0 and run.result.settled.k == 0


def test_diagnosis_counts_by_hand() -> None:
    """Five episodes of 100 steps, dt 0.5 s: onset at 10 in the first four, none in the last."""
    d = EpisodeDiagnosis(
        onset_step=np.array([10, 10, 10, 10, 100]),
        first_alarm_step=np.array([12, 4, -1, 10, 50]),  # late; early; never; on time; nominal alarm
        delay_steps=np.array([2, 0, -1, 0, -1]),  # the early alarm is still on at the onset
        false_alarms=np.array([0, 1, 0, 0, 1]),
        final_codes=np.array([[2, 0], [1, 0], [0, 0], [2, 1], [0, 1]]),
        truth_codes=np.array([[2, 0], [2, 0], [2, 0], [2, 0], [0, 0]]),
    )
    s = diagnosis_stats(d, steps=100, dt_s=0.5)
    assert (s.faulted, s.detected, s.isolated, s.severity_right) == (4, 3, 2, 1)
    assert s.delay_mean_s == pytest.approx((2 + 0 + 0) * 0.5 / 3) and s.delay_median_s == 0.0
    assert (s.healthy_episodes, s.false_alarm_episodes, s.false_alarms) == (5, 2, 2)
    assert s.healthy_hours == pytest.approx((4 * 10 + 100) * 0.5 / 3600)
    assert s.false_alarms_per_hour == pytest.approx(2 / s.healthy_hours)


SUBMISSION = f'''import numpy as np

SUBMISSION = {{
    "name": "toy_alarm",
    "version": "1.0.0",
    "authors": ["a tester"],
    "description": "raises a degraded alarm from its tenth step on",
    "entry": "Alarm",
    "license": "MIT",
    "benchmark": "{NAME}",
}}


class Alarm:
    def reset(self, n, context):
        self.n, self.k, self.units = n, 0, len(context.health_units)

    def act(self, obs):
        self.k += 1
        return np.clip(-(obs[:, :1] + 2.0 * obs[:, 1:2]), -1.0, 1.0)

    def health(self):
        return np.full((self.n, self.units), 1 if self.k >= 10 else 0, dtype=np.int64)
'''


@needs_sandbox
def test_health_reports_cross_the_sandbox_as_they_leave_the_process(toy: str, tmp_path: Path) -> None:
    from scftc_cli.board.draws import PUBLIC
    from scftc_cli.board.flights import Scoring, fly_submission
    from scftc_cli.submission.manifest import load_submission

    path = tmp_path / "toy_alarm.py"
    path.write_text(SUBMISSION)
    local = _cell("--controller-file", str(path))["diagnosis"]
    sub = load_submission(path)
    (sandboxed,) = fly_submission(sub, Scoring(get_spec(NAME)), PUBLIC, time.monotonic() + 120)[0]
    assert sandboxed.diagnosis is not None
    assert sandboxed.diagnosis.model_dump() == local
    assert local["detected"] == local["faulted"] and local["false_alarm_episodes"] > 0  # alarms from step 10
