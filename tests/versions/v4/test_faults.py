"""scftc-v4's recalibrated faults: what each class draws, how the plant applies the new kinds (the
fused kernel bit for bit with the reference), and the diagnosis truth of each."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scftc_cli.sim.testbed import testbed as bed_of
from scftc_cli.versions.v3.sim.dynamics import V3Plant
from scftc_cli.versions.v3.sim.fast import FastV3Plant
from scftc_cli.versions.v3.sim.faults import DrawnFault
from scftc_cli.versions.v3.sim.testbed import DEGRADED, FAILED, HEALTHY, diagnosis_truth
from scftc_cli.versions.v3.spec import UNITS, WHEEL_UNITS
from scftc_cli.versions.v4.spec import V4
from tests.versions.v3.sim.demo import random_plant_args
from tests.versions.v3.sim.helpers import rich_faults

BED = bed_of(V4.version)
WHEELS = [UNITS.index(w) for w in WHEEL_UNITS]


def draw(split: str, fault_class: str, n_faults: int = 8, n_seeds: int = 2):
    return BED.draw(split, fault_class, n_faults=n_faults, n_seeds=n_seeds)


@pytest.mark.parametrize("split", ["train", "test"])
def test_intermittent_wheel_drives_backwards_only_inside_its_bursts(split):
    episodes = draw(split, "intermittent")
    f = episodes.fault
    wheel = np.argmin(f.burst_gain, axis=1)
    rows = np.arange(episodes.n)
    assert V4.splits[split].flicker_gain == -1.0
    assert np.all(f.burst_gain[rows, wheel] == -1.0)
    assert np.all(np.sum(f.burst_gain != 1.0, axis=1) == 1)
    inside = outside = 0
    for k in range(0, V4.steps, 7):
        gain = f.gain_at(k)[rows, wheel]
        burst = f.in_burst(k)[:, 0] & (k >= f.onset_step)
        assert np.all(gain[burst] == -1.0) and np.all(gain[~burst] == 1.0)
        inside, outside = inside + burst.sum(), outside + (~burst).sum()
    assert inside > 0 and outside > 0


@pytest.mark.parametrize("split", ["train", "test"])
def test_incipient_is_a_dead_wheel_and_a_second_one_creeping_to_its_floor(split):
    episodes = draw(split, "incipient")
    f, ranges = episodes.fault, V4.splits[split]
    rows = np.arange(episodes.n)
    creeping = np.argmin(f.gain_creep_per_step, axis=1)
    dead = np.argmin(f.gain, axis=1)
    assert np.all(f.gain[rows, dead] == 0.0) and np.all(dead != creeping)
    floor = f.gain_creep_floor[rows, creeping]
    assert all(ranges.creep_end_gain.contains(x) for x in floor)
    duration_s = (floor - 1.0) / f.gain_creep_per_step[rows, creeping] * V4.dt_s
    assert all(ranges.creep_duration_s.contains(round(x, 6)) for x in duration_s)
    at_end = f.gain_at(V4.steps - 1)[rows, creeping]
    reached = f.onset_step + duration_s / V4.dt_s <= V4.steps - 1
    np.testing.assert_array_equal(at_end[reached], floor[reached])
    assert reached.any()
    truth = diagnosis_truth(episodes).codes
    assert np.all(truth[rows, np.array(WHEELS)[dead]] == FAILED)
    assert np.all(truth[rows, np.array(WHEELS)[creeping]] == DEGRADED)


@pytest.mark.parametrize("fault_class", ["double", "incipient"])
def test_a_three_wheel_class_holds_its_own_stored_momentum(fault_class):
    """``double`` and ``incipient`` fly with the momentum a three-wheel spacecraft keeps
    (``class_stored_momentum_nms``), not the split's."""
    for split in ("train", "test"):
        episodes = draw(split, fault_class, n_faults=4, n_seeds=3)
        ranges = V4.splits[split].class_stored_momentum_nms[fault_class]
        for h in _stored_momentum(episodes):
            assert ranges.contains(round(h, 9)), (split, h)


def _stored_momentum(episodes) -> list[float]:
    """``|h|`` of each episode's system momentum at the start (hub plus wheels), N m s."""
    from scftc_cli.versions.v2.sim.dynamics import MassProperties as V2Mass
    from scftc_cli.versions.v3.sim.dynamics import V2_WHEELS

    out = []
    for e in range(episodes.n):
        total = V2Mass.of(V2_WHEELS, np.array([episodes.inertia_scale[e]])).total_inertia_kgm2[0]
        hub = total @ episodes.omega0_rad_s[e]
        wheels = V2_WHEELS.js_kgm2 * (np.array(V4.plant.spin_axes).T @ episodes.wheel_speed0_rad_s[e])
        out.append(float(np.linalg.norm(hub + wheels)))
    return out


def test_train_sign_faults_reverse_exactly_one_wheel_and_held_out_two_or_three():
    for split, allowed in (("train", {1}), ("test", {2, 3})):
        f = draw(split, "sign", n_faults=20, n_seeds=1).fault
        assert set(np.sum(f.gain < 0.0, axis=1).tolist()) <= allowed
    assert set(np.sum(draw("test", "sign", n_faults=20, n_seeds=1).fault.gain < 0.0, axis=1).tolist()) == {
        2,
        3,
    }


def test_v4_draws_are_not_v3s():
    v3 = bed_of("scftc-v3").draw("train", "sign", n_faults=2, n_seeds=2)
    v4 = draw("train", "sign", n_faults=2, n_seeds=2)
    assert not np.array_equal(v3.sigma0, v4.sigma0)


def test_v3_faults_carry_exactly_neutral_creep_and_flicker():
    """v3's numbers keep their bits because its faults multiply every gain by exactly 1."""
    f = bed_of("scftc-v3").draw("train", "intermittent", n_faults=3, n_seeds=2).fault
    assert np.all(f.gain_creep_per_step == 0.0) and np.all(f.gain_creep_floor == 0.0)
    assert np.all(f.burst_gain == 1.0)
    for k in (0, 900, 2000):
        np.testing.assert_array_equal(f.gain_at(k), np.where((k >= f.onset_step)[:, None], f.gain, 1.0))


def test_fused_kernel_applies_creep_and_flicker_bit_for_bit_with_the_reference():
    n = 48
    rng = np.random.default_rng(40)
    args = random_plant_args(rng, n)
    base = rich_faults(n, 41)
    creep = np.where(rng.random((n, 4)) < 0.3, -rng.uniform(1e-3, 2e-2, (n, 4)), 0.0)
    floor = np.where(creep < 0.0, rng.choice([0.0, 0.05, 0.3], (n, 4)), 0.0)
    flicker = np.where(rng.random((n, 4)) < 0.3, rng.choice([-1.0, 0.0, 0.5], (n, 4)), 1.0)
    args["fault"] = dataclasses.replace(
        base, gain_creep_per_step=creep, gain_creep_floor=floor, burst_gain=flicker
    )
    ref, fused = V3Plant(**args), FastV3Plant(**args)
    crept = flickered = 0
    for k in range(300):
        cmd = rng.uniform(-1.0, 1.0, (n, 7))
        np.testing.assert_array_equal(fused.step(k, cmd), ref.step(k, cmd), err_msg=f"step {k}")
        np.testing.assert_array_equal(fused.wheel_speed_rad_s, ref.wheel_speed_rad_s, err_msg=f"step {k}")
        np.testing.assert_array_equal(fused.applied_torque_nm, ref.applied_torque_nm, err_msg=f"step {k}")
        g = ref.fault.gain_at(k)
        crept += int(np.sum((creep < 0.0) & (g != base.gain) & (k >= base.onset_step)[:, None]))
        flickered += int(np.sum((flicker != 1.0) & ref.fault.in_burst(k) & (k >= base.onset_step)[:, None]))
    assert crept > 100 and flickered > 100, (crept, flickered)


def test_truth_of_a_flickering_wheel_is_degraded_and_of_a_creep_to_zero_failed():
    f = rich_faults(2, 3)
    healthy = dataclasses.replace(
        f,
        gain=np.ones((2, 4)),
        bias=np.zeros((2, 4)),
        friction_multiplier=np.ones((2, 4)),
        friction_ramp_end=np.ones((2, 4)),
        burst_multiplier=np.ones((2, 4)),
        rod_gain=np.ones((2, 3)),
        onset_step=np.array([100, 100]),
        gain_creep_per_step=np.array([[-0.01, 0, 0, 0], [0, 0, 0, 0]]),
        gain_creep_floor=np.zeros((2, 4)),
        burst_gain=np.array([[1, 1, 1, 1], [1, -1.0, 1, 1]]),
        burst_start_step=np.tile([[150, 0, 0, 0]], (2, 1)),
        burst_end_step=np.tile([[200, 0, 0, 0]], (2, 1)),
    )
    episodes = dataclasses.replace(draw("train", "nominal", n_faults=1, n_seeds=2), fault=healthy)
    codes = diagnosis_truth(episodes).codes
    assert codes[0, WHEELS[0]] == FAILED and codes[1, WHEELS[1]] == DEGRADED
    assert codes[0, WHEELS[1]] == HEALTHY and codes[1, WHEELS[0]] == HEALTHY


def test_drawn_faults_default_to_no_creep_and_no_flicker():
    fields = {f.name: f.default for f in dataclasses.fields(DrawnFault)}
    assert fields["gain_creep_per_step"] is None and fields["burst_gain"] is None
