"""scftc-v3's Basilisk cross-check plan: every held-out class and sensor fault, pd and the teacher by
default, v2's state and checks with v3's tolerances. The one-step map restarts the reference plant
from recorded states: on the numpy backend (the reference's own bits) it lands exactly, and a fault
switched one step late is seen; on Basilisk the whole check passes."""

from __future__ import annotations

import dataclasses

import pytest

from scftc_cli.registry import make_controller
from scftc_cli.sim import testbed as testbeds
from scftc_cli.sim.rollout import rollout
from scftc_cli.study.crosscheck import crosscheck, default_controllers, plan
from scftc_cli.versions.v3.spec import V3
from scftc_cli.versions.v3.study import GROUPS, STEP_TOLERANCE, TOLERANCE, one_step

BED = testbeds.testbed(V3.version)


def test_the_groups_cover_every_held_out_class_and_sensor_fault():
    assert plan(V3.version).groups == GROUPS
    assert {g.fault_class for g in GROUPS if g.sensor is None} == set(V3.fault_classes)
    assert {g.sensor for g in GROUPS if g.sensor is not None} == set(V3.sensor_faults)
    assert all(g.split == "test" for g in GROUPS)
    assert default_controllers(V3.version) == ("pd", "teacher")


def test_the_one_step_map_lands_on_the_numpy_plants_states_exactly_and_sees_a_late_fault():
    episodes = BED.draw("test", "friction", n_faults=1, n_seeds=1)
    run = rollout(make_controller("pd", V3.version), episodes, record=True)
    diff, saturated, cut = one_step(episodes, run)
    assert diff == 0.0  # the fused kernel is the reference to the bit, environment and rods included
    assert saturated > 0 and cut > 0  # pd drives the faulted wheel into its speed limit
    late = dataclasses.replace(
        episodes, fault=dataclasses.replace(episodes.fault, onset_step=episodes.fault.onset_step + 1)
    )
    assert one_step(late, run)[0] > 1e-6


@pytest.mark.basilisk
def test_the_cross_check_passes_on_a_handful_of_episodes():
    pytest.importorskip("Basilisk")
    # pd alone (the teacher's runs cost as much and saturate nothing): a reversed and a friction wheel
    result = crosscheck(2, ("pd",), benchmark=V3.version)
    doc = result.dump()
    assert doc["benchmark_version"] == V3.version and doc["steps"] == V3.steps and doc["rollouts"] == 2
    assert doc["tolerance"] == TOLERANCE
    # measured (bsk 2.12.1, sign and friction): state 1.2e-9 (the friction wheel at its speed limit
    # under pd), one step 1.1e-13 (1 ulp of 600 rad/s)
    assert result.passed and result.gates_agree
    assert result.max_abs_step_diff <= STEP_TOLERANCE
    assert doc["saturated_steps"]["numpy"] == doc["saturated_steps"]["basilisk"] > 100
    assert doc["cut_wheel_steps"]["numpy"] == doc["cut_wheel_steps"]["basilisk"] > 100
