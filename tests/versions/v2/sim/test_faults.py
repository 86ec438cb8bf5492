"""``scftc-v2``'s taxonomy: train and test are disjoint in every parameter, draws are pinned and
sliceable, sensor cells pair with the ``sign`` cell, training batches follow the same rules."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.sim.mrp import principal_angle_deg
from scftc_cli.versions.v2.sim.faults import onset_step, pinned_episodes, sample_episodes_batch, sensor_code
from scftc_cli.versions.v2.sim.testbed import TESTBED
from scftc_cli.versions.v2.spec import V2

SPLITS = ("train", "test")
N_FAULTS, N_SEEDS = 40, 3


def _draw(split: str, fault_class: str, sensor: str | None = None, salt: bytes = b""):
    return TESTBED.draw(split, fault_class, sensor, N_FAULTS, N_SEEDS, salt)


def _reversed_counts_fit(ep, allowed: tuple[int, ...]) -> bool:
    """Each episode reversed a number of wheels in ``allowed`` (a dead wheel may have been one)."""
    reversed_wheels, dead = (ep.fault.gain < 0).sum(axis=1), (ep.fault.gain == 0).sum(axis=1)
    return bool((np.isin(reversed_wheels, allowed) | np.isin(reversed_wheels + dead, allowed)).all())


def _gain_magnitudes(ep) -> np.ndarray:
    g = np.abs(ep.fault.gain)
    return g[g > 0]


@pytest.mark.parametrize("split", SPLITS)
@pytest.mark.parametrize("fault_class", V2.fault_classes)
def test_every_actuator_parameter_lies_in_its_split(split: str, fault_class: str):
    ranges, ep = V2.splits[split], _draw(split, fault_class)
    assert ranges.inertia_scale.contains(ep.fault.inertia_scale).all()
    onset_s = ep.fault.onset_step * V2.dt_s
    lo, hi = (0, 60) if split == "train" else (61, 120)  # first k with k dt >= t_f
    assert ((ep.fault.onset_step >= lo) & (ep.fault.onset_step <= hi)).all(), onset_s
    assert _reversed_counts_fit(ep, ranges.reversed_wheels)
    if fault_class == "sign":
        assert set(np.abs(ep.fault.gain).ravel().tolist()) == {1.0}
    else:
        assert ranges.gain_magnitude.contains(_gain_magnitudes(ep)).all()
    dead = (ep.fault.gain == 0).sum(axis=1)
    assert (dead == (1 if fault_class == "loss" else 0)).all()
    offsets = ep.fault.bias
    if fault_class == "gain_bias":
        assert ranges.bias.contains(offsets).all()
    else:
        assert (offsets == 0).all()
    multiplier = ep.fault.friction_multiplier
    faulty = multiplier != 1.0
    if fault_class == "friction":
        assert (faulty.sum(axis=1) <= 1).all()
        assert ranges.friction_multiplier.contains(multiplier.max(axis=1)).all()
    else:
        assert not faulty.any()


@pytest.mark.parametrize("split", SPLITS)
def test_every_sensor_parameter_lies_in_its_split(split: str):
    ranges = V2.splits[split]
    biased = _draw(split, "sign", "st_bias")
    angles = principal_angle_deg(biased.sensor_fault.head_bias_mrp)
    assert ranges.head_bias_deg.contains(np.round(angles, 9)).all()
    step = _draw(split, "sign", "gyro_bias").sensor_fault.gyro_bias_step_rad_s
    assert ranges.gyro_bias_step_deg_s.contains(np.abs(np.degrees(step))).all()
    assert (step > 0).any() and (step < 0).any()
    for sensor in V2.sensor_faults:
        ep = _draw(split, "sign", sensor)
        assert (ep.sensor_fault.kind == sensor_code(V2, sensor)).all()
        assert set(ep.sensor_fault.head.tolist()) <= {0, 1, 2}


def test_train_and_test_are_disjoint_in_every_range():
    train, test = V2.splits["train"], V2.splits["test"]
    for field in type(train).model_fields:
        a, b = getattr(train, field), getattr(test, field)
        if isinstance(a, tuple):
            assert not set(a) & set(b), field
            continue
        probe = np.linspace(0.0, 100.0, 2_000_001)  # every range sits inside [0, 100]
        assert not (a.contains(probe) & b.contains(probe)).any(), field
        for part in a.parts:  # the shared endpoints belong to one side only
            for end in (part.lo, part.hi):
                assert not (a.contains(end) and b.contains(end)), (field, end)


def test_same_seeds_same_episodes_and_a_salt_changes_them():
    pinned_episodes.cache_clear()
    first = _draw("test", "friction")
    pinned_episodes.cache_clear()
    again = _draw("test", "friction")
    for name in ("gain", "bias", "friction_multiplier", "inertia_scale", "onset_step"):
        np.testing.assert_array_equal(getattr(first.fault, name), getattr(again.fault, name))
    np.testing.assert_array_equal(first.noise_seed, again.noise_seed)
    sealed = _draw("test", "friction", salt=b"\x01" * 32)
    assert not np.array_equal(first.fault.gain, sealed.fault.gain)
    assert not np.array_equal(first.noise_seed, sealed.noise_seed)


@settings(max_examples=15, deadline=None)
@given(start=st.integers(0, N_FAULTS * N_SEEDS - 1), length=st.integers(1, 40))
def test_a_slice_is_that_slice_of_the_whole_cell(start: int, length: int):
    stop = min(start + length, N_FAULTS * N_SEEDS)
    whole = TESTBED.draw("test", "gain_bias", None, N_FAULTS, N_SEEDS)
    part = TESTBED.draw("test", "gain_bias", None, N_FAULTS, N_SEEDS, b"", start, stop)
    expected = whole.subset(slice(start, stop))
    for a, b in zip(dataclasses.astuple(part.fault), dataclasses.astuple(expected.fault), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(part.sigma0, expected.sigma0)
    np.testing.assert_array_equal(part.wheel_speed0_rad_s, expected.wheel_speed0_rad_s)
    np.testing.assert_array_equal(part.noise_seed, expected.noise_seed)


def test_the_first_faults_do_not_depend_on_the_cell_size():
    small = TESTBED.draw("train", "loss", None, 5, 2)
    big = TESTBED.draw("train", "loss", None, 50, 10)
    keep = np.flatnonzero((big.fault_index < 5) & (big.seed_index < 2))
    np.testing.assert_array_equal(small.fault.gain, big.fault.gain[keep])
    np.testing.assert_array_equal(small.sigma0, big.sigma0[keep])
    np.testing.assert_array_equal(small.noise_seed, big.noise_seed[keep])


@pytest.mark.parametrize("sensor", V2.sensor_faults)
def test_a_sensor_cell_pairs_with_the_sign_cell(sensor: str):
    sign, faulted = _draw("test", "sign"), _draw("test", "sign", sensor)
    for a, b in zip(dataclasses.astuple(sign.fault), dataclasses.astuple(faulted.fault), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(sign.sigma0, faulted.sigma0)
    np.testing.assert_array_equal(sign.wheel_speed0_rad_s, faulted.wheel_speed0_rad_s)
    np.testing.assert_array_equal(sign.noise_seed, faulted.noise_seed)  # the same noise: pairs cleanly


def test_draws_are_read_only():
    ep = _draw("train", "sign")
    with pytest.raises(ValueError):
        ep.fault.gain[0, 0] = 2.0


def test_onset_step_is_the_first_step_at_or_after_the_onset():
    t = np.array([0.0, 0.25, 0.5, 0.5000001, 30.0, 30.0000001, 60.0])
    np.testing.assert_array_equal(onset_step(t, 0.5), [0, 1, 1, 2, 60, 61, 120])


def test_unknown_cells_name_the_choices():
    with pytest.raises(UnknownNameError, match="friction"):
        TESTBED.draw("test", "frictoin")
    with pytest.raises(UsageError, match="on top of `sign`"):
        TESTBED.draw("test", "gain", "st_bias")
    with pytest.raises(UnknownNameError, match="st_stuck"):
        TESTBED.draw("test", "sign", "stuck")


@pytest.mark.parametrize("split", SPLITS)
def test_training_batches_follow_the_split_rules(split: str):
    ranges = V2.splits[split]
    rng = np.random.default_rng(0)
    ep = sample_episodes_batch(rng, 4000, split, V2.fault_classes, (None, *V2.sensor_faults))
    assert ranges.inertia_scale.contains(ep.fault.inertia_scale).all()
    assert _reversed_counts_fit(ep, ranges.reversed_wheels)
    assert ranges.gain_magnitude.contains(_gain_magnitudes(ep)[_gain_magnitudes(ep) != 1.0]).all()
    assert ranges.bias.contains(ep.fault.bias[ep.fault.bias != 0]).all()
    assert ranges.friction_multiplier.contains(
        ep.fault.friction_multiplier[ep.fault.friction_multiplier != 1]
    ).all()
    kinds = np.bincount(ep.sensor_fault.kind, minlength=5)
    assert (kinds > 600).all()  # five choices, uniform
    sensor_faulted = ep.sensor_fault.kind > 0
    assert set(np.abs(ep.fault.gain[sensor_faulted]).ravel().tolist()) == {1.0}  # on sign faults
    again = sample_episodes_batch(
        np.random.default_rng(0), 4000, split, V2.fault_classes, (None, *V2.sensor_faults)
    )
    np.testing.assert_array_equal(ep.fault.gain, again.fault.gain)
