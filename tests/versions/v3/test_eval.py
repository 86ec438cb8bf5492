"""``scftc-v3`` through the command line at a reduced size: every window scored, the diagnosis
scored beside the gates, a perfect diagnosis scoring perfectly, a silent controller never
alarming, and the fdir controller detecting and isolating a failed wheel from its own residuals."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.baselines.checker import check_controller
from scftc_cli.commands.app import app
from scftc_cli.registry import make_controller
from scftc_cli.sim import testbed as testbeds
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions import get_version
from scftc_cli.versions.v3.controllers.analytic import PD
from scftc_cli.versions.v3.controllers.fdir import FDIR
from scftc_cli.versions.v3.spec import UNITS

runner = CliRunner()


def _cell(*args: str) -> dict:
    result = runner.invoke(
        app,
        ["eval", "--benchmark", "scftc-v3", "--n-faults", "2", "--n-seeds", "1", "--format", "json", *args],
    )
    assert result.exit_code == 0, result.output
    (cell,) = json.loads(result.stdout)["cells"]
    return cell


def test_the_teacher_settles_every_window_with_a_perfect_diagnosis():
    cell = _cell("--controller", "teacher", "--class", "loss", "--split", "train")
    n = cell["n"]
    assert cell["window_settled"] == [n, n, n] and cell["settled"]["k"] == n
    d = cell["diagnosis"]
    assert (d["faulted"], d["detected"], d["isolated"], d["severity_right"]) == (n, n, n, n)
    assert d["delay_mean_s"] == 0.0 and d["false_alarm_episodes"] == 0


def test_the_fault_unaware_pd_reports_nothing():
    cell = _cell("--controller", "pd", "--class", "nominal", "--split", "train")
    assert cell["settled"]["k"] == cell["n"]
    d = cell["diagnosis"]
    assert d["faulted"] == 0 and d["false_alarm_episodes"] == 0 and d["healthy_episodes"] == cell["n"]


def test_every_v3_controller_passes_the_protocol_checker():
    for entry in get_version("scftc-v3").controllers:
        check_controller(make_controller(entry.name, "scftc-v3"), benchmark="scftc-v3")


def test_fdir_finds_the_dead_wheel_from_its_own_residuals():
    bed = testbeds.testbed("scftc-v3")
    episodes = bed.draw("train", "double", n_faults=2, n_seeds=1)
    flown = rollout(FDIR(), episodes, steps=int(episodes.fault.onset_step.max()) + 200)
    assert flown.health is not None
    truth = bed.diagnosis_truth(episodes)
    wheels = [UNITS.index(u) for u in UNITS if u.startswith("wheel")]
    dead = truth.codes[:, wheels] == 2
    assert np.all(flown.health.final_codes[:, wheels][dead] == 2)
    assert np.all(flown.health.first_alarm_step >= truth.onset_step)  # no alarm before the onset


@pytest.mark.basilisk
def test_the_basilisk_backend_flies_the_mission_like_the_fused_kernel():
    pytest.importorskip("Basilisk")
    bed = testbeds.testbed("scftc-v3")
    episodes = bed.draw("train", "rod", n_faults=1, n_seeds=1)
    ours = rollout(PD(), episodes, steps=40, record=True)
    theirs = rollout(PD(), episodes, backend="basilisk", steps=40, record=True)
    assert ours.error_deg is not None and theirs.error_deg is not None
    assert np.abs(ours.error_deg - theirs.error_deg).max() < 1e-9
