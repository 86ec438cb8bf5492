"""scftc-v4's ports: the privileged law at its tuned gains, the RMA students' v4 training (the target
is the gain in force as it moves), and a port still in training, refused by name and flown only
from the file its trainer wrote."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli import versions
from scftc_cli.baselines.params import committed_params
from scftc_cli.commands.app import app
from scftc_cli.sim import testbed as testbeds
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions import get_version
from scftc_cli.versions.v2.controllers.law import KD_S, KP_S2
from scftc_cli.versions.v2.controllers.student import LAYOUT, StudentConfig

runner = CliRunner()
BED = testbeds.testbed("scftc-v4")


def test_the_oracle_and_the_teacher_fly_the_oracles_tuned_gains():
    from scftc_cli.versions.v4.controllers.analytic import Oracle, Teacher
    from scftc_cli.versions.v4.controllers.rma import law_gains

    tuned = committed_params("oracle", "scftc-v4")
    assert (tuned["kp_s2"], tuned["kd_s"]) != (KP_S2, KD_S)  # not v3's (v2's) gains
    for controller in (Oracle(), Teacher()):
        assert (controller.params.kp_s2, controller.params.kd_s) == (tuned["kp_s2"], tuned["kd_s"])
    assert dataclasses.asdict(law_gains()) == tuned  # the students fly them too


def test_different_law_gains_fly_differently():
    from scftc_cli.versions.v4.controllers.analytic import LawGains, Oracle

    episodes = BED.draw("train", "double", n_faults=2, n_seeds=1)
    flown = [
        rollout(Oracle(gains), episodes, steps=300).min_error_deg
        for gains in (LawGains(), LawGains(**committed_params("oracle", "scftc-v4")))
    ]
    assert not np.array_equal(flown[0], flown[1])


def test_the_collector_targets_the_gain_in_force_as_it_creeps():
    torch = pytest.importorskip("torch")
    from scftc_cli.training.dagger import student_net
    from scftc_cli.training.student import StudentModule
    from scftc_cli.versions.v4.training.rma import DaggerMission

    episodes = BED.draw("train", "incipient", n_faults=2, n_seeds=1)
    onset = np.asarray(episodes.fault.onset_step)
    steps = int(onset.max()) + 40
    torch.manual_seed(0)
    model = StudentModule(LAYOUT, 8, False)
    collector = DaggerMission(
        student_net(model, LAYOUT, False), StudentConfig(hidden=8), np.ones(2, dtype=bool)
    )
    rollout(collector, episodes, steps=steps)
    targets = np.stack(collector.targets).reshape(steps, 2, 4)  # (T, n, m)
    expected = np.stack([episodes.fault.gain_at(k) for k in range(steps)]).astype(np.float32)
    np.testing.assert_array_equal(targets, expected)
    for e in range(2):
        assert np.all(targets[: onset[e], e] == 1.0)
        creeping = targets[onset[e] :, e]
        assert (np.diff(creeping, axis=0) < 0).any()  # a gain that moves after the onset, not v3's step


@pytest.fixture
def rma_dob_in_training(monkeypatch):
    """v4 as it was before ``rma_dob``'s weights were committed: the port listed in training."""
    version = get_version("scftc-v4")
    entry = next(c for c in version.controllers if c.name == "rma_dob")
    battery = tuple(c for c in version.controllers if c.name != "rma_dob")
    pending = dataclasses.replace(version, controllers=battery, in_training=(*version.in_training, entry))
    monkeypatch.setitem(versions._loaded, "scftc-v4", pending)  # the loaded record, its package kept


def test_a_port_in_training_is_refused_by_name_with_the_command_that_makes_it(rma_dob_in_training):
    result = runner.invoke(
        app,
        ["eval", "--benchmark", "scftc-v4", "--controller", "rma_dob", "--split", "train"]
        + ["--class", "sign", "--n-faults", "1", "--n-seeds", "1"],
    )
    assert result.exit_code == 2, result.output
    assert "still in training" in result.output and "scftc train --benchmark scftc-v4" in result.output


@pytest.mark.slow
def test_a_port_in_training_trains_and_flies_from_its_file(tmp_path, monkeypatch, rma_dob_in_training):
    pytest.importorskip("torch")
    from scftc_cli.training import TrainRequest
    from scftc_cli.versions.v4.training import rma

    tiny = dict(
        iterations=2, episodes=3, grad_steps=2, minibatch=8, eval_every=2, eval_faults=1, eval_seeds=1
    )
    monkeypatch.setitem(rma.BUDGETS, "quick", dataclasses.replace(rma.BUDGETS["quick"], **tiny))
    monkeypatch.setitem(rma.CLASSES, "rma_dob", ("nominal", "incipient"))
    out = tmp_path / "rma_dob.npz"
    report = rma.train_student(
        TrainRequest(controller="rma_dob", benchmark="scftc-v4", seed=0, budget="quick", out=out)
    )
    assert report.artifact == out
    result = runner.invoke(
        app,
        [
            "eval",
            "--benchmark",
            "scftc-v4",
            "--controller",
            "rma_dob",
            "--params",
            str(out),
            "--split",
            "train",
        ]
        + ["--class", "incipient", "--n-faults", "1", "--n-seeds", "1", "--format", "json"],
    )
    assert result.exit_code == 0, result.output


def test_a_port_in_training_reserves_its_name_on_every_board(rma_dob_in_training):
    from scftc_cli.registry import builtin_names

    assert {"residual_ppo", "e2e_ppo", "rma_dob"} <= builtin_names()
