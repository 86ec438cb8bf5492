"""The taxonomy: held-out by construction, pinned, and different where it should be."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scftc_cli.errors import UnknownNameError
from scftc_cli.versions.v1.sim.faults import pinned_episodes, sample_fault
from scftc_cli.versions.v1.sim.testbed import TESTBED
from scftc_cli.versions.v1.spec import V1 as SPEC

FAULT_CLASSES = SPEC.fault_classes

OTHER = {"train": "test", "test": "train"}


def _membership(split: str, gain: np.ndarray, bias: np.ndarray, scale: float, fault_class: str) -> dict:
    """Whether each parameter of one fault could have been drawn from ``split``."""
    spec = SPEC.splits[split]
    alive = gain != 0
    out = {
        "inertia_scale": bool(spec.inertia_scale.contains(scale)),
        "sign_pattern": int(np.sum(gain < 0)) in spec.reversed_axes,
    }
    if fault_class != "sign":
        out["gain_magnitude"] = bool(np.any(spec.gain_magnitude.contains(np.abs(gain[alive]))))
    if fault_class == "gain_bias":
        out["bias"] = bool(np.any(spec.bias.contains(bias)))
    return out


@settings(max_examples=300, deadline=None)
@given(
    split=st.sampled_from(["train", "test"]),
    fault_class=st.sampled_from([c for c in FAULT_CLASSES if c != "loss"]),
    seed=st.integers(0, 2**63),
)
def test_no_fault_of_one_split_could_come_from_the_other(split, fault_class, seed):
    gain, bias, scale = sample_fault(
        SPEC.splits[split], SPEC.fault_class(fault_class), np.random.default_rng(seed)
    )
    assert all(_membership(split, gain, bias, scale, fault_class).values())
    assert not any(_membership(OTHER[split], gain, bias, scale, fault_class).values())


@settings(max_examples=200, deadline=None)
@given(split=st.sampled_from(["train", "test"]), seed=st.integers(0, 2**63))
def test_loss_kills_exactly_one_axis_and_keeps_the_rest_held_out(split, seed):
    gain, bias, scale = sample_fault(
        SPEC.splits[split], SPEC.fault_class("loss"), np.random.default_rng(seed)
    )
    assert np.sum(gain == 0) == 1 and np.all(bias == 0)
    alive = gain[gain != 0]
    assert np.all(SPEC.splits[split].gain_magnitude.contains(np.abs(alive)))
    assert not np.any(SPEC.splits[OTHER[split]].gain_magnitude.contains(np.abs(alive)))
    assert not SPEC.splits[OTHER[split]].inertia_scale.contains(scale)


@settings(max_examples=200, deadline=None)
@given(u=st.floats(0.0, 1.0, exclude_max=True))
def test_interval_sampling_never_lands_on_an_open_end(u):
    for split in SPEC.splits.values():
        for ranges in (split.inertia_scale, split.gain_magnitude, split.bias):
            for part in ranges.parts:
                assert part.contains(part.from_unit(np.array([u])))[0]


def test_union_is_sampled_by_length():
    x = SPEC.splits["test"].gain_magnitude.sample(np.random.default_rng(0), 200_000)
    # [0.3, 0.5) has length 0.2 and (1.5, 2.0] length 0.5: 2/7 of the mass is low.
    assert np.mean(x < 0.5) == pytest.approx(2 / 7, abs=0.005)


def test_sign_pattern_count_is_uniform_over_allowed_counts():
    rng = np.random.default_rng(1)
    counts = [
        int(np.sum(sample_fault(SPEC.splits["test"], SPEC.fault_class("sign"), rng)[0] < 0))
        for _ in range(4000)
    ]
    assert set(counts) == {2, 3}
    assert np.mean(np.array(counts) == 3) == pytest.approx(0.5, abs=0.03)


def test_same_seeds_give_the_same_episodes():
    a, b = (
        TESTBED.draw("test", "gain_bias", n_faults=5, n_seeds=3),
        pinned_episodes.__wrapped__("test", "gain_bias", None, 5, 3, b"", 0, 15),  # a fresh draw
    )
    assert a is not b
    for x, y in [
        (a.fault.gain, b.fault.gain),
        (a.fault.bias, b.fault.bias),
        (a.sigma0, b.sigma0),
        (a.omega0_rad_s, b.omega0_rad_s),
        (a.fault.inertia_scale, b.fault.inertia_scale),
    ]:
        np.testing.assert_array_equal(x, y)


def test_cached_cells_are_shared_and_read_only():
    a = TESTBED.draw("test", "gain", n_faults=5, n_seeds=3)
    assert TESTBED.draw("test", "gain", n_faults=5, n_seeds=3) is a
    for array in (a.fault.gain, a.fault.bias, a.fault.inertia_scale, a.sigma0, a.omega0_rad_s):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0.0


def test_a_cell_prefix_does_not_depend_on_its_size():
    small, full = TESTBED.draw("test", "gain", n_faults=3, n_seeds=2), TESTBED.draw("test", "gain")
    idx = (full.fault_index < 3) & (full.seed_index < 2)
    np.testing.assert_array_equal(small.sigma0, full.sigma0[idx])
    np.testing.assert_array_equal(small.fault.gain, full.fault.gain[idx])


def test_different_classes_splits_and_salts_differ():
    base = TESTBED.draw("test", "sign", n_faults=5, n_seeds=2)
    for other in (
        TESTBED.draw("test", "gain", n_faults=5, n_seeds=2),
        TESTBED.draw("train", "sign", n_faults=5, n_seeds=2),
        TESTBED.draw("test", "sign", n_faults=5, n_seeds=2, salt=b"secret"),
    ):
        assert not np.array_equal(base.sigma0, other.sigma0)


def test_sensor_cells_pair_with_the_sign_cell():
    sign = TESTBED.draw("test", "sign", n_faults=4, n_seeds=2)
    for sensor in SPEC.sensor_faults:
        cell = TESTBED.draw("test", "sign", sensor, n_faults=4, n_seeds=2)
        np.testing.assert_array_equal(cell.sigma0, sign.sigma0)
        np.testing.assert_array_equal(cell.fault.gain, sign.fault.gain)
    bias = TESTBED.draw("test", "sign", "bias_0.3", n_faults=4, n_seeds=2).sensor_bias_mrp
    np.testing.assert_allclose(4 * np.degrees(np.arctan(np.linalg.norm(bias, axis=1))), 0.3)


def test_every_cell_has_500_episodes_by_default_and_unknown_names_are_rejected():
    assert TESTBED.draw("test", "loss").n == 500
    with pytest.raises(UnknownNameError, match="did you mean `gain_bias`"):
        TESTBED.draw("test", "gain_bais")
