"""The v3 plant's physics: momentum, the external torque, the rods, the fault schedule, unloading."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scftc_cli.sim.mrp import cross, to_dcm
from scftc_cli.versions.v2.sim.dynamics import MassProperties, kinetic_energy_j
from scftc_cli.versions.v3.sim.dynamics import (
    V2_WHEELS,
    PlantFault,
    V3Constants,
    V3Plant,
    derivatives,
    external_torque_nm,
)
from scftc_cli.versions.v3.sim.environment import gravity_gradient_terms, orbit_position_m
from scftc_cli.versions.v3.sim.fast import FastV3Plant
from tests.versions.v3.sim.demo import random_environment, random_plant_args, unit_vectors
from tests.versions.v3.sim.helpers import (
    CONSTANTS,
    M_MAX,
    WHEELS,
    command,
    inertial_momentum,
    quiet,
    wheel_momentum,
    wheel_speeds_for,
)

NO_GRAVITY_GRADIENT = dataclasses.replace(
    CONSTANTS, environment=dataclasses.replace(CONSTANTS.environment, gravity_gradient=False)
)


def test_the_wheel_plant_is_v2s():
    assert CONSTANTS.wheels == V2_WHEELS
    assert CONSTANTS.dt_s == 0.5 and CONSTANTS.episode_steps == 2400 and CONSTANTS.action_dim == 7
    assert CONSTANTS.environment.rod_dipole_max_am2 == 10.0


def test_the_external_torque_enters_the_hub_equation_and_nothing_else():
    # d/dt (I_tot w + Js sum_i Omega_i g_i) = -w x H + L at the derivative level: the motor and
    # friction torques stay internal, the external torque L changes the total momentum.
    rng = np.random.default_rng(1)
    n = 32
    sigma, omega = rng.uniform(-0.5, 0.5, (n, 3)), rng.uniform(-0.05, 0.05, (n, 3))
    wheel, motor = rng.uniform(-600, 600, (n, 4)), rng.uniform(-0.1, 0.1, (n, 4))
    external = rng.uniform(-1e-3, 1e-3, (n, 3))
    mass = MassProperties.of(WHEELS, rng.uniform(0.7, 2.3, n))
    _, omega_dot, wheel_accel = derivatives(
        sigma, omega, wheel, motor, np.full((n, 4), 20 * WHEELS.coulomb_nm), external, mass, WHEELS
    )
    rate = np.einsum("nij,nj->ni", mass.total_inertia_kgm2, omega_dot) + wheel_momentum(wheel_accel)
    h = np.einsum("nij,nj->ni", mass.total_inertia_kgm2, omega) + wheel_momentum(wheel)
    np.testing.assert_allclose(rate, -cross(omega, h) + external, rtol=0, atol=2e-15)


def _coast(constants: V3Constants, dt_s: float, stored_nms: float, seed: int = 2) -> float:
    """Relative drift of the inertial momentum over 1200 s: hub rates up to 0.002 rad/s, the wheels
    holding ``stored_nms``, no command, no residual dipole, no solar pressure; with the gravity
    gradient off nothing external acts."""
    rng = np.random.default_rng(seed)
    n = 16
    constants = dataclasses.replace(constants, wheels=dataclasses.replace(constants.wheels, dt_s=dt_s))
    plant = FastV3Plant(
        sigma0=rng.uniform(-0.5, 0.5, (n, 3)),
        omega0_rad_s=rng.uniform(-0.002, 0.002, (n, 3)),
        wheel_speed0_rad_s=wheel_speeds_for(stored_nms * unit_vectors(rng, n)),
        inertia_scale=rng.uniform(0.7, 2.3, n),
        fault=PlantFault.healthy(n),
        environment=quiet(random_environment(rng, n)),
        constants=constants,
    )
    h0 = inertial_momentum(plant)
    e0 = kinetic_energy_j(plant.omega_rad_s, plant.wheel_speed_rad_s, plant.mass, plant.constants.wheels)
    for k in range(round(1200.0 / dt_s)):
        plant.step(k, np.zeros((n, 7)))
    if constants.wheels.coulomb_nm == 0.0:  # no friction and no motor: no power either
        e1 = kinetic_energy_j(plant.omega_rad_s, plant.wheel_speed_rad_s, plant.mass, plant.constants.wheels)
        np.testing.assert_allclose(e1, e0, rtol=1e-9)
    return float(np.abs(inertial_momentum(plant) - h0).max() / np.linalg.norm(h0, axis=1).min())


FRICTIONLESS = dataclasses.replace(NO_GRAVITY_GRADIENT, wheels=dataclasses.replace(WHEELS, coulomb_nm=0.0))


def test_with_nothing_external_momentum_and_energy_are_conserved():
    # Motors and friction are internal; with the environment off (gravity gradient off, no
    # residual dipole, no facet, rods at zero) the total momentum is fixed in inertial space, to
    # RK4's truncation. That grows with the stored momentum, whose nutation (~|h| / I rad/s) RK4
    # resolves at dt = 0.5 s: measured over 1200 s, 1.3e-14 of |H| with idle wheels, 3.2e-13 at
    # 0.1 N m s, 4.5e-11 at 0.5, 3.8e-9 at 1.5 (32x less at dt/2: fifth order in the step). With
    # friction off the kinetic energy is constant too: measured 7.9e-15 at 0.1 N m s, 5.2e-12 at 1.5.
    assert _coast(FRICTIONLESS, 0.5, 0.1) < 1e-12
    # friction on: still internal, but it hands the wheels' momentum to the hub, whose rates grow
    # to ~|h| / I: measured 2.5e-11
    assert _coast(NO_GRAVITY_GRADIENT, 0.5, 0.1) < 1e-10
    drift = {dt: _coast(FRICTIONLESS, dt, 1.5) for dt in (0.5, 0.25)}
    assert drift[0.5] < 1e-8 and drift[0.5] / drift[0.25] > 16.0, drift


def test_the_environment_changes_the_momentum_by_its_impulse():
    # H_N(T) - H_N(0) = integral of C(sigma)' L dt, where over each step L sees the field of the
    # step's start (held, as Basilisk's) and the attitude and position of the moment: the
    # trapezoid rule on that integrand agrees to O(dt^2) (measured 1.1e-6 of the impulse;
    # with the field taken at each end instead, a first-order 5e-4: the field turns n dt per step).
    rng = np.random.default_rng(3)
    n = 8
    args = random_plant_args(rng, n, faults=False)
    args["omega0_rad_s"] = rng.uniform(-0.002, 0.002, (n, 3))
    args["environment"] = dataclasses.replace(args["environment"], residual_dipole_am2=unit_vectors(rng, n))
    plant = V3Plant(**args)
    c = CONSTANTS.environment
    inertia = plant.mass.total_inertia_kgm2

    def torque_n(sigma, position, field_n):
        r_hat, coefficient = gravity_gradient_terms(position, c.gravity_gradient_factor)
        torque = external_torque_nm(
            sigma,
            r_hat,
            coefficient,
            field_n,
            plant.env.residual_dipole_am2,
            plant.env,
            plant.geometry,
            inertia,
            c,
        )
        return np.einsum("nji,nj->ni", to_dcm(sigma), torque)

    h0 = inertial_momentum(plant)
    impulse = np.zeros((n, 3))
    for k in range(800):
        sigma, position, field = plant.sigma.copy(), plant.position_m.copy(), plant.field_n_t.copy()
        plant.step(k, np.zeros((n, 7)))
        start, end = torque_n(sigma, position, field), torque_n(plant.sigma, plant.position_m, field)
        impulse += 0.5 * CONSTANTS.dt_s * (start + end)
    h1 = inertial_momentum(plant)
    assert np.abs(impulse).max() > 5e-3  # the residual dipole alone: ~1e-5 N m over 400 s
    np.testing.assert_allclose(h1 - h0, impulse, rtol=0, atol=1e-5 * np.abs(impulse).max())


def test_the_rods_torque_is_their_dipole_cross_the_body_field_with_their_faults():
    rng = np.random.default_rng(4)
    n = 12
    args = random_plant_args(rng, n, faults=False)
    args["environment"] = quiet(args["environment"])
    fault = PlantFault.healthy(n)
    rod_gain = np.tile([[-1.0, 0.0, 0.5]], (n, 1))  # reversed, dead, half
    args["fault"] = dataclasses.replace(fault, rod_gain=rod_gain, onset_step=np.full(n, 10))
    for cls in (V3Plant, FastV3Plant):
        plant = cls(**args, constants=NO_GRAVITY_GRADIENT)
        for k in range(20):
            cmd = rng.uniform(-1.3, 1.3, (n, 7))
            field_before = plant.field_b_t.copy()
            plant.step(k, cmd)
            gain = rod_gain if k >= 10 else 1.0
            dipole = gain * (np.clip(cmd[:, 4:], -1.0, 1.0) * M_MAX)
            np.testing.assert_array_equal(plant.dipole_am2, dipole)
            np.testing.assert_array_equal(plant.external_torque_nm, np.cross(dipole, field_before))
        # the strongest torque the rods can make here: all three saturated, across the field
        bound = np.sqrt(3.0) * M_MAX * np.linalg.norm(plant.field_b_t, axis=1)
        assert np.all(np.linalg.norm(plant.external_torque_nm, axis=1) <= 1.0001 * bound)


def test_the_fault_schedule():
    n, m = 3, 4
    fault = PlantFault(
        gain=np.array([[0.0, 0.5, 1.0, 1.0]] * n), bias=np.zeros((n, m)),
        friction_multiplier=np.array([[2.0, 1.0, 1.0, 1.0]] * n),
        friction_ramp_end=np.array([[1.0, 41.0, 1.0, 1.0]] * n),
        burst_multiplier=np.array([[1.0, 1.0, 30.0, 1.0]] * n),
        burst_start_step=np.array([[700, 100, 0], [0, 0, 0], [500, 600, 1500]]),
        burst_end_step=np.array([[900, 120, 0], [0, 0, 0], [900, 650, 1600]]),
        rod_gain=np.array([[-1.0, 1.0, 1.0]] * n), onset_step=np.array([400, 400, 2000]),
    )  # fmt: skip
    plant = V3Plant(**random_plant_args(np.random.default_rng(5), n, faults=False) | {"fault": fault})
    fc0 = WHEELS.coulomb_nm
    gain, bias, coulomb, rod = plant.faults_at(399)  # healthy before the onset
    np.testing.assert_array_equal(gain, 1.0)
    np.testing.assert_array_equal(coulomb, fc0)
    np.testing.assert_array_equal(rod, 1.0)
    gain, _, coulomb, rod = plant.faults_at(400)
    np.testing.assert_array_equal(gain[0], [0.0, 0.5, 1.0, 1.0])  # a double fault: dead plus degraded
    np.testing.assert_array_equal(rod[0], [-1.0, 1.0, 1.0])
    np.testing.assert_array_equal(coulomb[0], [2 * fc0, fc0, fc0, fc0])  # ramp at 1, no burst yet
    # the ramp: linear in steps, 1 at the onset, the end multiplier at the episode's end (step 2400)
    for k in (400, 1400, 2399):
        expected = 1.0 + 40.0 * (k - 400) / 2000
        assert plant.faults_at(k)[2][1, 1] == pytest.approx(expected * fc0, rel=1e-15)
    # bursts: only inside [start, end) and only from the onset on (episode 2: onset 2000)
    burst = np.array([plant.faults_at(k)[2][:, 2] for k in range(2400)]) > fc0
    assert [np.flatnonzero(np.diff(burst[:, 0].astype(int))).tolist()] == [[699, 899]]
    assert not burst[:, 1].any() and not burst[:, 2].any()


def _linear_zone_limit() -> float:
    """The Coulomb multiplier beyond which RK4 at dt = 0.5 s is unstable inside the linear zone:
    there a free wheel's speed decays at ``lambda = -(k fC0 / wLC) / Js`` (the hub's share,
    ~1e-4 of it, neglected) and RK4's real stability limit is ``lambda dt = -2.785``."""
    return 2.785293 * WHEELS.omega_linear_rad_s * WHEELS.js_kgm2 / (WHEELS.dt_s * WHEELS.coulomb_nm)


@pytest.mark.parametrize("fraction, stable", [(0.97, True), (1.03, False)])
def test_friction_beyond_the_rk4_linear_zone_limit_diverges(fraction, stable):
    limit = _linear_zone_limit()
    assert limit == pytest.approx(106.4, abs=0.1)  # the stability limit of RK4 at dt = 0.5 s
    n = 2
    args = random_plant_args(np.random.default_rng(6), n, faults=False)
    args["wheel_speed0_rad_s"] = np.full((n, 4), 0.0)
    args["wheel_speed0_rad_s"][:, 0] = 2.0  # inside the linear zone (|Omega| < 3 rad/s)
    args["omega0_rad_s"] = np.zeros((n, 3))
    fault = PlantFault.healthy(n)
    args["fault"] = dataclasses.replace(
        fault, friction_multiplier=np.array([[fraction * limit, 1, 1, 1]] * n)
    )
    plant = V3Plant(**args, constants=NO_GRAVITY_GRADIENT)
    for k in range(200):
        plant.step(k, np.zeros((n, 7)))
    assert (np.abs(plant.wheel_speed_rad_s[:, 0]).max() < 1e-3) == stable


def test_orbit_time_and_position_advance_with_the_steps():
    args = random_plant_args(np.random.default_rng(7), 4, faults=False)
    plant = V3Plant(**args)
    for k in range(10):
        plant.step(k, np.zeros((4, 7)))
    assert plant.time_s == 5.0
    g = plant.geometry
    c, s = (
        np.cos(plant.env.arg_latitude0_rad + g.mean_motion * 5.0),
        np.sin(plant.env.arg_latitude0_rad + g.mean_motion * 5.0),
    )
    np.testing.assert_array_equal(
        plant.position_m, orbit_position_m(plant.env.semi_major_axis_m, g.p, g.q, c, s)
    )


def test_cross_product_unloading_drains_the_wheels_over_an_episode():
    # A PD hold with the rods' torque fed forward, the wheels holding 1.5 N m s: with the
    # cross-product law the rods drain the momentum across the field, which turns with the orbit;
    # without it the wheels keep their momentum (the environment's impulse is ~0.01 N m s).
    rng = np.random.default_rng(8)
    n = 8
    args = random_plant_args(rng, n, faults=False)
    args["sigma0"], args["omega0_rad_s"] = np.zeros((n, 3)), np.zeros((n, 3))
    args["wheel_speed0_rad_s"] = wheel_speeds_for(1.5 * unit_vectors(rng, n))
    drained = {}
    for gain in (0.0, 0.02):
        plant = FastV3Plant(**args)
        for k in range(2400):
            plant.step(k, command(plant, unload_gain=gain))
        drained[gain] = 1.5 - np.linalg.norm(wheel_momentum(plant.wheel_speed_rad_s), axis=1)
        assert np.degrees(4 * np.arctan(np.sqrt(plant.sigma_norm2))).max() < 0.05  # the hold held
    assert np.abs(drained[0.0]).max() < 0.05, drained
    assert drained[0.02].min() > 0.2, drained  # measured 0.32-0.58 N m s over 1200 s
