"""scftc-v4's Basilisk cross-check plan: v3's checks on every held-out class and sensor fault of v4.
v4's time-varying wheel gains (a creeping gain, a wheel reversed inside its bursts) step identically
in the one-step replay, and one is seen if it moves a step late."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scftc_cli.registry import make_controller
from scftc_cli.sim import testbed as testbeds
from scftc_cli.sim.rollout import rollout
from scftc_cli.study.crosscheck import crosscheck, default_controllers, plan
from scftc_cli.versions.v3.study import one_step
from scftc_cli.versions.v4.spec import V4
from scftc_cli.versions.v4.study import GROUPS

BED = testbeds.testbed(V4.version)


def test_the_groups_cover_every_held_out_class_and_sensor_fault():
    assert plan(V4.version).groups == GROUPS
    assert {g.fault_class for g in GROUPS if g.sensor is None} == set(V4.fault_classes)
    assert {g.sensor for g in GROUPS if g.sensor is not None} == set(V4.sensor_faults)
    assert all(g.split == "test" for g in GROUPS)
    assert default_controllers(V4.version) == ("pd", "teacher")


@pytest.mark.parametrize("fault_class", ["incipient", "intermittent"])
def test_the_one_step_map_steps_v4s_moving_gains_exactly_and_sees_them_late(fault_class):
    episodes = BED.draw("test", fault_class, n_faults=1, n_seeds=1)
    run = rollout(make_controller("teacher", V4.version), episodes, record=True)
    assert one_step(episodes, run)[0] == 0.0  # the fused kernel is the reference to the bit
    fault = episodes.fault
    moved = np.array([fault.gain_at(k) for k in range(V4.steps)])
    onset = int(fault.onset_step[0])
    assert len(np.unique(moved[onset:, 0], axis=0)) > 1  # the gain moves after its onset: not v3's step
    late = dataclasses.replace(episodes, fault=dataclasses.replace(fault, onset_step=fault.onset_step + 1))
    assert one_step(late, run)[0] > 1e-9


@pytest.mark.slow
def test_the_teacher_flies_a_weak_wheel_alike_on_both_backends():
    pytest.importorskip("Basilisk")
    result = crosscheck(2, ("teacher",), benchmark=V4.version)  # sign, then double
    assert result.passed, result.state_failures()
    assert result.benchmark_version == V4.version and result.gates_agree
