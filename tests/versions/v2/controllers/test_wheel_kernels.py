"""The per-wheel pieces compiled from their numpy definitions (the RMA student's feature builder
and latch, the law's friction prediction and allocation): the same bits, step after step, signed
zeros and NaNs included."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.sim.scalars import lu_inverse
from scftc_cli.versions.v2.controllers.latch import WheelLatch
from scftc_cli.versions.v2.controllers.law import friction_nm, pseudo_inverse
from scftc_cli.versions.v2.controllers.student import N_FEATURES, LatchConfig, wheel_features
from scftc_cli.versions.v2.sim.testbed import public_context
from tests.bits import bits
from tests.oracles import v2_latch, v2_law, v2_student


def _awkward(rng: np.random.Generator, shape: tuple[int, int], scale: float) -> np.ndarray:
    """Normal draws with exact zeros of both signs, values past every clip, and a few NaNs."""
    v = rng.normal(0.0, scale, shape)
    pick = rng.random(shape)
    v[pick < 0.08] = 0.0
    v[(pick >= 0.08) & (pick < 0.14)] = -0.0
    v[(pick >= 0.14) & (pick < 0.17)] *= 1e3
    v[(pick >= 0.17) & (pick < 0.18)] = np.nan
    return v


@pytest.mark.parametrize("n", [1, 9, 5_003])  # one episode, a few, past the parallel threshold
def test_the_compiled_features_give_the_bits_of_their_numpy_definition(n: int) -> None:
    rng = np.random.default_rng(n)
    shape = (n, 4)
    for _ in range(5):
        floats = [_awkward(rng, shape, s) for s in (0.3, 0.3, 0.05, 0.05, 1.0, 0.5, 5.0)]
        after_alarm = (rng.random(shape) < 0.2).astype(float)
        flags = [rng.random(shape) < p for p in (0.2, 0.7, 0.5)]
        compiled = wheel_features(*floats, after_alarm, *flags)
        reference = v2_student.wheel_features(*floats, after_alarm, *flags)
        assert compiled.shape == (n * 4, N_FEATURES)
        np.testing.assert_array_equal(bits(compiled), bits(reference))


def test_the_features_of_a_sign_change_under_the_clip() -> None:
    """A clipped pair reads ``sign(y a)`` (+0.0 for either zero); the clips hold at their bounds."""
    a = np.array([[0.5, -0.5, 0.0, -0.0]])
    y = np.array([[-1.0, -1.0, 1.0, 1.0]])
    zero, flag = np.zeros((1, 4)), np.ones((1, 4), dtype=bool)
    innovation = np.array([[50.0, -50.0, 3.0, -0.0]])
    f = wheel_features(a, y, zero, zero, zero, zero, innovation, zero, flag, flag, ~flag)
    np.testing.assert_array_equal(f[:, 13], [-1.0, 1.0, 0.0, 0.0])
    assert not np.signbit(f[2:, 13]).any()
    np.testing.assert_array_equal(f[:, 10], [10.0, -10.0, 3.0, -0.0])
    assert np.signbit(f[3, 10])


@pytest.mark.parametrize("n", [1, 9, 5_003])
def test_the_compiled_latch_gives_the_bits_of_its_numpy_definition(n: int) -> None:
    rng = np.random.default_rng(100 + n)
    config = LatchConfig()
    compiled, reference = (WheelLatch(config, (n, 4)) for _ in range(2))
    level = rng.normal(1.0, 0.3, (n, 4))
    mixed = False  # a step with latched and unlatched wheels side by side
    for step in range(3 * config.max_steps):
        noise = np.where(rng.random((n, 4)) < 0.5, 1e-4, 0.1)  # some wheels settle, some never do
        raw = level + rng.normal(0.0, 1.0, (n, 4)) * noise
        raw[rng.random((n, 4)) < 0.02] = -0.0
        raw[rng.random((n, 4)) < 0.002] = np.nan
        excitation = rng.random((n, 4)) * 2.0 * config.min_excitation
        if step in (40, 130):
            restart = rng.random((n, 4)) < 0.3
            compiled.restart(restart)
            reference.restart(restart)
        got, want = compiled.update(raw, excitation), v2_latch.update(reference, raw, excitation)
        np.testing.assert_array_equal(bits(got), bits(want))
        np.testing.assert_array_equal(compiled.latched, reference.latched)
        np.testing.assert_array_equal(compiled.count, reference.count)
        np.testing.assert_array_equal(bits(compiled.frozen), bits(reference.frozen))
        np.testing.assert_array_equal(bits(compiled.history), bits(reference.history))
        mixed |= bool(compiled.latched.any()) and not compiled.latched.all()
    assert mixed  # both branches were taken


@pytest.mark.parametrize(
    "coulomb",
    [5e-4, "per wheel", "per episode", "per episode and wheel", "strided", "negative"],
)
@pytest.mark.parametrize("n", [1, 5_003])
def test_the_compiled_friction_gives_the_bits_of_its_numpy_definition(coulomb: object, n: int) -> None:
    rng = np.random.default_rng(n)
    wheels = public_context(1).wheels
    assert wheels is not None
    linear = wheels.omega_linear_rad_s
    observation = rng.normal(0.0, 3.0 * linear, (n, 19))  # the tachometers as a strided column block
    speed = observation[:, 15:19]
    speed[rng.random((n, 4)) < 0.05] = 0.0
    speed[rng.random((n, 4)) < 0.05] = -0.0
    speed[rng.random((n, 4)) < 0.05] = linear
    speed[rng.random((n, 4)) < 0.05] = -linear
    speed[rng.random((n, 4)) < 0.01] = np.nan
    levels = {
        "per wheel": rng.normal(5e-4, 1e-4, 4),
        "per episode": rng.normal(5e-4, 1e-4, (n, 1)),
        "per episode and wheel": rng.normal(5e-4, 1e-4, (n, 4)),
        "strided": rng.normal(5e-4, 1e-4, (n, 8))[:, ::2],
        "negative": -rng.normal(5e-4, 1e-4, (n, 4)),
    }.get(str(coulomb), coulomb)
    with np.errstate(invalid="ignore"):
        got, want = friction_nm(speed, levels, wheels), v2_law.friction_nm(speed, levels, wheels)
    assert got.shape == want.shape == (n, 4)
    np.testing.assert_array_equal(bits(got), bits(want))


@pytest.mark.parametrize("wheels", [3, 4, 5])
@pytest.mark.parametrize("n", [1, 9, 5_003])
def test_the_compiled_allocation_gives_the_bits_of_its_numpy_definition(wheels: int, n: int) -> None:
    """``pseudo_inverse`` of ``G diag(g)`` as the allocation builds it, with dead wheels (a zero
    column of either sign), rows that lose rank and all-zero rows (the damping's floor): its
    numpy form around the same 3x3 inverse (the project's ``lu_inverse``, checked on its own in
    tests/sim/test_scalars.py)."""
    rng = np.random.default_rng(10 * n + wheels)
    axes = rng.normal(size=(wheels, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    axes[0] = (1.0, 0.0, 0.0)  # exact zeros in the products
    gain = rng.normal(1.0, 0.5, (n, wheels)) * 10.0 ** rng.integers(-3, 3, (n, 1))
    gain[rng.random((n, wheels)) < 0.1] = 0.0
    gain[rng.random((n, wheels)) < 0.05] = -0.0
    gain[: min(n, 2)] = 0.0
    matrix = axes.T[None, :, :] * gain[:, None, :]
    got, want = pseudo_inverse(matrix), v2_law.pseudo_inverse(matrix, invert=lu_inverse)
    assert got.shape == want.shape == (n, wheels, 3)
    np.testing.assert_array_equal(bits(got), bits(want))
    assert np.isfinite(got).all()
