"""``fdir``'s wheel detector (v2) compiled gives the bits of its numpy form
(``tests/oracles/v2_detection.py``): ``WheelMonitor.observe`` (``_observe_rows``) flown in lockstep
with the numpy ``observe`` through faults that alarm, confirm changes and kill wheels, through
clipped commands, speed-limited wheels and zero crossings, and through a NaN reading (skipped by
both); the ridge solve and clamp (``solved``, ``clamped``) against their numpy forms, on values
that pin every bound, signed zeros and infinite covariances."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scftc_cli.sim.products import split_matvec3
from scftc_cli.versions.v2.controllers.detection import WheelMonitor, clamped, over_buffer, solved
from scftc_cli.versions.v2.controllers.fdir import load_fdir_params
from scftc_cli.versions.v2.sim.testbed import public_context
from tests.bits import bits
from tests.oracles import v2_detection as oracle

CONTEXT = public_context(1)
SENSORS, WHEELS, DT = CONTEXT.sensors, CONTEXT.wheels, CONTEXT.dt_s
assert SENSORS is not None and WHEELS is not None
VISCOUS = dataclasses.replace(WHEELS, viscous_nms=2e-6)  # the flight's wheels have none


class NumpyMonitor(WheelMonitor):
    """The detector on its numpy definitions."""

    observe = oracle.observe
    solver = staticmethod(oracle.solved)


STATE = ("theta", "cov", "A", "y", "prior", "prior_weight", "cusum", "since_zero", "isolated", "dead")
BUFFERS = ("buf_x", "buf_tau", "buf_ok", "buf_z", "buf_tested", "detected_step")


def _fly(n: int, wheels, steps: int = 140, nan_at: int | None = None) -> tuple[WheelMonitor, int]:
    """Fly a compiled and a numpy monitor in lockstep on synthetic wheels (gain losses, an offset,
    dead wheels, clipped commands, speeds across zero and at the limit); assert every piece of
    state equal to the bit after every step; returns the compiled monitor and how many steps had
    an alarm."""
    rng = np.random.default_rng(n)
    m, u, js = len(wheels.spin_axes), wheels.u_max_nm, wheels.spin_inertia_kgm2
    settings = load_fdir_params().detector()
    compiled = WheelMonitor(n, wheels, SENSORS, DT, settings)
    reference = NumpyMonitor(n, wheels, SENSORS, DT, settings)
    speed = rng.uniform(-6.0, 6.0, (n, m))
    speed[::5, 0] = wheels.omega_max_rad_s - 0.2  # at the limit: never testable
    gain, bias = np.ones((n, m)), np.zeros((n, m))
    gyro = rng.normal(0.0, 1e-3, (n, 3))
    alarms = 0
    for k in range(steps):
        if k == 40:
            gain[: n // 2 + 1, 1] = 0.3
            bias[n // 2 :, 2] = 0.2
        if k == 90:
            gain[::3, 3 % m] = 0.0
        command = np.clip(rng.uniform(-1.15, 1.15, (n, m)), -1.0, 1.0)
        command[::4] = np.sign(command[::4])  # clipped commands
        for monitor in (compiled, reference):
            monitor.commanded(command)
        torque = u * np.clip(gain * command + bias, -1.0, 1.0) - wheels.coulomb_nm * np.clip(
            speed / 3.0, -1, 1
        )
        speed = np.where(speed > wheels.omega_max_rad_s - 1.0, speed, speed + DT * torque / js)
        gyro = gyro + rng.normal(0.0, 1e-5, (n, 3))
        tach = speed + SENSORS.tachometer_noise_rad_s * rng.standard_normal((n, m))
        if nan_at is not None and k == nan_at:
            tach[n // 2, 0] = np.nan
        compiled.observe(tach, gyro)
        reference.observe(tach, gyro)
        for name in STATE + BUFFERS:
            got, want = getattr(compiled, name), getattr(reference, name)
            assert np.array_equal(bits(got), bits(want)), f"{name} differs at step {k}"
        for log in ("alarm_log", "statistic_log", "change_log"):
            assert np.array_equal(bits(getattr(compiled, log)[-1]), bits(getattr(reference, log)[-1])), log
        alarms += bool(compiled.alarm_log[-1].any())
    return compiled, alarms


@pytest.mark.parametrize("n", [1, 13, 300])  # one episode (numpy's one-row product), a few, threaded
def test_the_compiled_detector_gives_the_bits_of_its_numpy_definition(n: int) -> None:
    monitor, alarms = _fly(n, WHEELS)
    assert alarms > 0  # the faults were seen: the alarm path ran
    assert (monitor.detected_step >= 0).any()  # and a change was confirmed


def test_the_same_bits_with_viscous_friction_and_a_nan_reading() -> None:
    monitor, _ = _fly(13, VISCOUS, steps=80, nan_at=30)
    assert np.isfinite(monitor.theta).all()  # a NaN reading is not testable: skipped, never fitted


def _solve_inputs(rng: np.random.Generator, shape: tuple[int, ...]) -> tuple[np.ndarray, ...]:
    x = rng.normal(0.0, 1.0, (*shape, 6, 3))
    A = np.einsum("...ki,...kj->...ij", x, x) * rng.uniform(0.01, 100.0, (*shape, 1, 1))
    y = rng.normal(0.0, 30.0, (*shape, 3))  # estimates far past the bounds: every component pinned
    weight = rng.uniform(0.1, 1e4, (*shape, 3))
    prior = rng.normal(0.0, 2.0, (*shape, 3))
    return A, y, weight, prior


@pytest.mark.parametrize("shape", [(1, 1), (7, 4), (300, 4)])
def test_the_compiled_solve_and_clamp_give_the_bits_of_numpy(shape: tuple[int, int]) -> None:
    A, y, weight, prior = _solve_inputs(np.random.default_rng(sum(shape)), shape)
    for got, want in zip(solved(A, y, weight, prior), oracle.solved(A, y, weight, prior), strict=True):
        np.testing.assert_array_equal(bits(got), bits(want))


def test_the_clamp_moves_every_row_when_one_moves_as_numpy_does() -> None:
    """Where one row's component is pinned, numpy adds ``column * 0.0`` to every row: a -0.0
    estimate becomes +0.0 and an infinite one NaN where its covariance column is infinite; where
    none is, nothing moves but the clip."""
    rng = np.random.default_rng(5)
    theta = rng.uniform(-0.5, 0.5, (40, 3))
    theta[:, 2] = np.abs(theta[:, 2])  # inside every bound
    x = rng.normal(0.0, 1.0, (40, 6, 3))
    cov = np.einsum("rki,rkj->rij", x, x)
    theta[3] = -0.0
    theta[7, 1], cov[7, 1, 2], cov[7, 1, 0] = np.inf, np.inf, np.inf
    theta[9, 0] = np.nan
    for pinned in (None, (11, 2), (12, 0), (13, 1)):
        t, c = theta.copy(), cov.copy()
        if pinned is not None:
            t[pinned] = 7.5  # past its bound
        with np.errstate(invalid="ignore"):  # inf * 0.0, as intended
            want_theta, want_cov = oracle.clamp(t.copy(), c.copy())
        clamped(t, c)
        np.testing.assert_array_equal(bits(t), bits(want_theta))
        np.testing.assert_array_equal(bits(c), bits(want_cov))
        if pinned is not None and pinned[1] != 1:
            assert not np.signbit(t[3]).all()  # the -0.0 row was moved by 0.0 too


def test_the_window_sums_are_in_their_stated_order() -> None:
    """``over_buffer`` adds the buffer's slots left to right from slot 0, then +0.0 (a sum of -0.0
    terms is +0.0), exactly; the refit's sums and the samples' fit (``split_matvec3``) are the
    window's least-squares terms (``einsum``'s contractions) to rounding."""
    rng = np.random.default_rng(48)
    B, a, m = 12, 9, 4
    x = rng.normal(size=(B, a, m, 3)) * 10.0 ** rng.integers(-4, 4, (B, a, m, 1))
    inside = rng.random((B, a, m)) < 0.6
    inside[:, 0, 0] = False  # every product a zero, some -0.0
    tau = rng.normal(size=(B, a, m))
    theta = rng.normal(size=(a, m, 3))
    xw = x * inside[..., None] / 0.3
    terms = xw[..., :, None] * xw[..., None, :]
    loop = np.zeros(terms.shape[1:])
    for b in range(B):
        loop = loop + terms[b]
    got = over_buffer(terms)
    np.testing.assert_array_equal(bits(got), bits(loop))
    assert not np.signbit(got[0, 0]).any() and np.signbit(terms[:, 0, 0]).any()
    np.testing.assert_allclose(got, np.einsum("bnmi,bnmj->nmij", xw, xw), rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(
        over_buffer(xw * tau[..., None]), np.einsum("bnmi,bnm->nmi", xw, tau), rtol=1e-12, atol=1e-300
    )
    fitted = np.moveaxis(split_matvec3(np.moveaxis(x, 0, -2), theta), -1, 0)
    np.testing.assert_allclose(fitted, np.einsum("bnmi,nmi->bnm", x, theta), rtol=1e-12, atol=1e-300)
