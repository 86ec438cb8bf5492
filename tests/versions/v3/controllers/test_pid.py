"""scftc-v3's ``pid`` port: the mission law plus v2's integral action. Without integral gain it is
``pd`` to the bit; its integrator winds only in a dwell with no wheel clipped, and stays clamped;
its tuner flies train episodes only and writes parameters inside its box (``PID_SPACE``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

from scftc_cli.sim import testbed as testbeds
from scftc_cli.sim.rollout import rollout
from scftc_cli.training import TrainRequest, tuning
from scftc_cli.versions.v2.controllers.pid import PIDParams
from scftc_cli.versions.v3.controllers.analytic import PD
from scftc_cli.versions.v3.controllers.pid import PID
from scftc_cli.versions.v3.spec import V3
from scftc_cli.versions.v3.training.tuning import SPECS

BED = testbeds.testbed("scftc-v3")


def test_without_integral_gain_pid_is_pd_to_the_bit():
    episodes = BED.draw("train", "gain_bias", n_faults=2, n_seeds=1)
    steps = 900  # past the first window's end: a slew and part of a second dwell
    a = rollout(PD(), episodes, record=True, steps=steps)
    b = rollout(PID(PIDParams(ki_s3=0.0)), episodes, record=True, steps=steps)
    assert a.commands is not None and b.commands is not None
    np.testing.assert_array_equal(a.commands, b.commands)


def test_the_integral_winds_only_in_a_dwell_with_no_wheel_clipped_and_stays_clamped():
    episodes = BED.draw("train", "nominal", n_faults=3, n_seeds=1)
    params = PIDParams(ki_s3=0.01, integral_cap=0.2, integrate_below=0.05)
    pid = PID(params)
    pid.reset(3, BED.context(episodes, False))
    error = np.array([[0.01, -0.02, 0.0], [0.2, 0.0, 0.0], [0.01, 0.01, 0.01]])
    wheels = np.array([[0.5, 0.1, -0.3, 0.0], [0.1, 0.1, 0.1, 0.1], [1.0, 0.0, 0.0, 0.0]])
    pid.commanded(error, wheels)
    dt = V3.dt_s
    np.testing.assert_array_equal(pid.z[0], dt * error[0])  # small error, unclipped: winds
    np.testing.assert_array_equal(pid.z[1], [0.0, dt * 0.0, 0.0])  # the x error is a slew's: holds
    np.testing.assert_array_equal(pid.z[2], 0.0)  # a wheel at its limit: holds
    for _ in range(200):
        pid.commanded(np.full((3, 3), 0.05), np.zeros((3, 4)))
    cap = params.integral_cap * pid.wheels.u_max_nm / (pid.context.inertia_nominal_kgm2 * params.ki_s3)
    np.testing.assert_allclose(pid.z, np.broadcast_to(cap, (3, 3)))  # clamped per axis


@pytest.mark.slow
def test_quick_tuning_flies_train_episodes_only_and_writes_parameters_in_the_box(tmp_path, monkeypatch):
    seen = []
    original = BED.draw

    def recording(split, fault_class, *args, **kwargs):
        episodes = original(split, fault_class, *args, **kwargs)
        seen.append(episodes)
        return episodes

    monkeypatch.setattr(BED, "draw", recording)  # every door to the episodes: tuning and scoring
    request = TrainRequest(
        controller="pid", benchmark="scftc-v3", seed=0, budget="quick", out=tmp_path / "p.yaml"
    )
    report = tuning.tune(SPECS["pid"], request)
    assert seen and {e.split for e in seen} == {"train"}
    for episodes in seen:
        assert np.all(V3.splits["train"].inertia_scale.contains(np.asarray(episodes.inertia_scale)))
    doc = yaml.safe_load(report.artifact.read_text())
    params = PIDParams(**doc["params"])
    for dim in SPECS["pid"].space:
        low, high = dim.bounds()
        assert low - 1e-12 <= dim.encode(getattr(params, dim.name)) <= high + 1e-12, dim.name
    assert doc["provenance"]["command"].startswith("scftc train --benchmark scftc-v3 --controller pid")
    assert doc["provenance"]["benchmark_version"] == "scftc-v3"
    assert dataclasses.asdict(params).keys() == dataclasses.asdict(PIDParams()).keys()
