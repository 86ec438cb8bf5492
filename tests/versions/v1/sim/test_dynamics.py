"""Physics checks of the reference integrator: invariants, order of accuracy, MRP switching."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.sim.mrp import compose, principal_angle_deg, shadow_switch, to_dcm
from scftc_cli.versions.v1.sim.dynamics import rk4_step
from scftc_cli.versions.v1.spec import V1 as SPEC

INERTIA_NOMINAL = np.array(SPEC.plant.inertia_nominal_kgm2)


def _tumbling_batch(n: int = 64, rate_rad_s: float = 0.1, seed: int = 0):
    rng = np.random.default_rng(seed)
    sigma = rng.uniform(-0.5, 0.5, (n, 3))
    omega = rng.uniform(-rate_rad_s, rate_rad_s, (n, 3))
    inertia = rng.uniform(0.7, 2.3, (n, 1)) * INERTIA_NOMINAL
    return sigma, omega, inertia


def _energy(omega, inertia):
    return 0.5 * np.sum(inertia * omega**2, axis=1)


def _inertial_momentum(sigma, omega, inertia):
    return np.einsum("nji,nj->ni", to_dcm(sigma), inertia * omega)  # [NB] I w = C^T (I w)


def test_torque_free_motion_conserves_energy_and_inertial_momentum():
    # Rates of the benchmark's initial conditions (|w_i| <= 0.02 rad/s). RK4's truncation error
    # grows like (|w| dt)^5: at 0.1 rad/s the momentum drifts ~1e-7 over an episode, honestly so.
    sigma, omega, inertia = _tumbling_batch(rate_rad_s=SPEC.plant.omega0_half_width_rad_s)
    e0, h0 = _energy(omega, inertia), _inertial_momentum(sigma, omega, inertia)
    zero = np.zeros_like(omega)
    for _ in range(SPEC.plant.steps):
        sigma, omega = rk4_step(sigma, omega, zero, inertia, SPEC.plant.dt_s)
    np.testing.assert_allclose(_energy(omega, inertia), e0, rtol=1e-9, atol=0)
    np.testing.assert_allclose(_inertial_momentum(sigma, omega, inertia), h0, rtol=0, atol=1e-9)


def _integrate(sigma, omega, torque, inertia, dt_s: float, duration_s: float):
    for _ in range(round(duration_s / dt_s)):
        sigma, omega = rk4_step(sigma, omega, torque, inertia, dt_s)
    return np.concatenate((sigma, omega), axis=1)


def test_rk4_is_fourth_order():
    sigma, omega, inertia = _tumbling_batch(n=8, rate_rad_s=0.3, seed=1)
    sigma *= 0.2  # stay clear of the shadow switch so the comparison is smooth
    torque = np.random.default_rng(2).uniform(-0.2, 0.2, (8, 3))
    reference = _integrate(sigma, omega, torque, inertia, 0.5 / 16, 20.0)
    err = [
        np.max(np.abs(_integrate(sigma, omega, torque, inertia, dt, 20.0) - reference)) for dt in (0.5, 0.25)
    ]
    assert 2.0**3.5 < err[0] / err[1] < 2.0**4.5, err


def test_every_step_keeps_sigma_in_the_unit_ball_and_switching_preserves_attitude():
    sigma, omega, inertia = _tumbling_batch(n=128, rate_rad_s=0.3, seed=3)
    zero = np.zeros_like(omega)
    for _ in range(SPEC.plant.steps):
        sigma, omega = rk4_step(sigma, omega, zero, inertia, SPEC.plant.dt_s)
        assert np.all(np.linalg.norm(sigma, axis=1) <= 1.0)
    outside = np.random.default_rng(4).uniform(-3, 3, (256, 3))
    outside = outside[np.linalg.norm(outside, axis=1) > 1.0]
    shadow = shadow_switch(outside)
    assert len(outside) > 100
    assert np.all(np.linalg.norm(shadow, axis=1) <= 1.0)
    np.testing.assert_allclose(to_dcm(shadow), to_dcm(outside), atol=1e-12)


def test_compose_matches_dcm_product_and_small_bias_offsets_the_angle():
    rng = np.random.default_rng(5)
    a, b = rng.uniform(-0.6, 0.6, (50, 3)), rng.uniform(-0.3, 0.3, (50, 3))
    np.testing.assert_allclose(to_dcm(compose(a, b)), to_dcm(b) @ to_dcm(a), atol=1e-12)
    bias = np.array([[0.0, 0.0, np.tan(np.radians(0.3) / 4)]])
    assert principal_angle_deg(compose(np.zeros((1, 3)), bias)) == pytest.approx(0.3)
