"""Physics checks of the v2 reference plant: constants, invariants, order, saturation, friction, faults."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from scftc_cli.sim.mrp import cross, norm2, to_dcm
from scftc_cli.versions.v2.sim.dynamics import (
    MassProperties,
    WheelPlant,
    body_momentum_nms,
    derivatives,
    friction_torque_nm,
    kinetic_energy_j,
    motor_torque_nm,
    rk4_step,
)
from tests.versions.v2.sim.episodes import CONSTANTS, faulted, healthy, pd_command

FRICTIONLESS = dataclasses.replace(CONSTANTS, coulomb_nm=0.0)
OMEGA_MAX = CONSTANTS.omega_max_rad_s
U_MAX = CONSTANTS.u_max_nm


def _inertial_momentum(plant_or_state, mass=None, constants=CONSTANTS):
    sigma, omega, wheel = plant_or_state
    return np.einsum("nji,nj->ni", to_dcm(sigma), body_momentum_nms(omega, wheel, mass, constants))


def test_constants_are_spec_v2():
    c = CONSTANTS
    assert c.omega_max_rad_s == pytest.approx(6000 * 2 * np.pi / 60, rel=1e-15)
    assert c.js_kgm2 == pytest.approx(2.0 / (200 * np.pi), rel=1e-15)  # h_max / Omega_max
    assert c.jt_kgm2 == 0.5 * c.js_kgm2
    friction = (c.coulomb_nm, c.viscous_nms, c.omega_linear_rad_s)
    assert (c.u_max_nm, *friction, c.dt_s, c.inertia_nominal_kgm2) == (0.1, 5e-4, 0.0, 3.0, 0.5, (10, 8, 6))
    axes = c.axes
    np.testing.assert_allclose(np.abs(axes) * np.sqrt(3.0), 1.0, rtol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(axes, axis=1), 1.0, rtol=1e-15)
    for triple in itertools.combinations(range(4), 3):  # one dead wheel leaves three-axis control
        assert abs(np.linalg.det(axes[list(triple)])) > 0.3
    # sum_i g_i g_i' = 4/3 1 for the tetrahedron: I_tot = I_hub + 8/3 Js 1, D = I_hub + 4/3 Js 1
    scale = np.array([0.7, 1.0, 2.3])
    hub = scale[:, None, None] * np.diag([10.0, 8.0, 6.0])
    np.testing.assert_allclose(c.total_inertia_kgm2(scale), hub + 8 / 3 * c.js_kgm2 * np.eye(3), atol=1e-15)
    np.testing.assert_allclose(c.coupled_inertia_kgm2(scale), hub + 4 / 3 * c.js_kgm2 * np.eye(3), atol=1e-15)


def test_the_coupled_inverse_is_the_projects_own():
    """``MassProperties``' ``D^-1`` comes from ``sim/scalars.lu_inverse`` (no LAPACK): for the
    benchmark's wheels ``D`` is diagonal and its inverse exactly the reciprocal diagonal; for a
    tilted wheel array (a full ``D``) it is the inverse to rounding."""
    scale = np.random.default_rng(3).uniform(0.5, 2.0, 257)
    coupled = CONSTANTS.coupled_inertia_kgm2(scale)
    inverse = MassProperties.of(CONSTANTS, scale).coupled_inertia_inv
    off = ~np.eye(3, dtype=bool)
    assert (coupled[:, off] == 0.0).all()
    assert (inverse[:, off] == 0.0).all()
    np.testing.assert_array_equal(
        np.diagonal(inverse, axis1=1, axis2=2), 1.0 / np.diagonal(coupled, axis1=1, axis2=2)
    )
    axes = np.random.default_rng(4).normal(size=(4, 3))
    axes /= np.sqrt(norm2(axes))[:, None]
    tilted = dataclasses.replace(CONSTANTS, spin_axes=tuple(map(tuple, axes)))
    full = tilted.coupled_inertia_kgm2(scale)
    assert (np.abs(full[:, off]) > 1e-5).all()  # a full matrix
    np.testing.assert_allclose(
        MassProperties.of(tilted, scale).coupled_inertia_inv, np.linalg.inv(full), rtol=1e-12, atol=1e-16
    )


def test_constants_reject_nonsense():
    with pytest.raises(ValueError, match="unit"):
        dataclasses.replace(CONSTANTS, spin_axes=((1.0, 1.0, 0.0),))
    with pytest.raises(ValueError, match="u_max_nm"):
        dataclasses.replace(CONSTANTS, u_max_nm=0.0)


def test_internal_torques_leave_the_total_momentum_rate_gyroscopic():
    # d/dt (I_tot w + sum Js Omega g) = -w x H exactly in the equations, whatever the motor and
    # friction torques (they act between wheel and hub): a wrong sign or a missing coupling
    # term shows up here at O(1e-3), rounding at O(1e-17).
    args = healthy(64, seed=0)
    rng = np.random.default_rng(1)
    wheel = args["wheel_speed0_rad_s"].copy()
    wheel[:16] = rng.uniform(-3.0, 3.0, (16, 4))  # inside the linear friction zone too
    motor = rng.uniform(-U_MAX, U_MAX, (64, 4))
    coulomb = rng.uniform(0.0, 0.03, (64, 4))
    mass = MassProperties.of(CONSTANTS, args["inertia_scale"])
    omega = args["omega0_rad_s"]
    _, omega_dot, wheel_accel = derivatives(args["sigma0"], omega, wheel, motor, coulomb, mass, CONSTANTS)
    momentum_rate = np.einsum("nij,nj->ni", mass.total_inertia_kgm2, omega_dot) + (
        CONSTANTS.js_kgm2 * wheel_accel @ CONSTANTS.axes
    )
    assert np.abs(momentum_rate).max() > 1e-3  # the torques do move hub and wheels
    gyro = -cross(omega, body_momentum_nms(omega, wheel, mass, CONSTANTS))
    np.testing.assert_allclose(momentum_rate, gyro, rtol=0, atol=1e-15)


def _coast(args, constants, dt_s, duration_s=200.0):
    """Integrate with no command and the friction of ``constants``; returns the states per step."""
    mass = MassProperties.of(constants, args["inertia_scale"])
    state = (args["sigma0"], args["omega0_rad_s"], args["wheel_speed0_rad_s"])
    zero = np.zeros_like(state[2])
    coulomb = np.full_like(zero, constants.coulomb_nm)
    states = [state]
    for _ in range(round(duration_s / dt_s)):
        state = rk4_step(*state, zero, coulomb, mass, constants, dt_s)
        states.append(state)
    return states, mass


def test_torque_free_motion_conserves_inertial_momentum_and_energy():
    # Friction off, no command: total momentum fixed in inertial space, energy constant. The
    # residual is RK4's truncation error, not a modelling error: it shrinks ~16x when dt halves.
    # Its size: ~(|w| dt)^5 per step in attitude, times |H| ~ 0.8 N m s (the wheels' +-1000 rpm):
    # measured 5.8e-10 N m s over the 400-step episode, 3.6e-11 at dt/2.
    args = healthy(64, seed=2)
    drift = {}
    for dt_s in (0.5, 0.25):
        states, mass = _coast(args, FRICTIONLESS, dt_s)
        h0, h1 = (_inertial_momentum(s, mass, FRICTIONLESS) for s in (states[0], states[-1]))
        drift[dt_s] = np.abs(h1 - h0).max()
        e0, e1 = (kinetic_energy_j(s[1], s[2], mass, FRICTIONLESS) for s in (states[0], states[-1]))
        np.testing.assert_allclose(e1, e0, rtol=1e-11)
    assert np.abs(h0).max() > 0.3
    assert drift[0.5] < 2e-9
    assert drift[0.5] / drift[0.25] > 10.0, drift


def test_friction_only_dissipates_energy_every_step_and_keeps_momentum():
    args = healthy(64, seed=3)
    args["wheel_speed0_rad_s"][:16] = np.random.default_rng(4).uniform(-3.0, 3.0, (16, 4))  # linear zone
    states, mass = _coast(args, CONSTANTS, 0.5)
    energy = np.array([kinetic_energy_j(s[1], s[2], mass, CONSTANTS) for s in states])
    assert np.all(np.diff(energy, axis=0) < 0.0)
    h0, h1 = (_inertial_momentum(s, mass) for s in (states[0], states[-1]))
    np.testing.assert_allclose(h1, h0, rtol=0, atol=2e-9)  # friction is internal


def test_motors_and_friction_keep_momentum_in_closed_loop():
    # A PD loop with scaled gains, offsets, friction up to 60x and dead wheels: every wheel torque
    # is internal. The drift is again RK4's truncation (hub rates reach 0.09 rad/s while the loop
    # slews): measured 8.1e-8 at dt = 0.5, 16x smaller at dt/2.
    args = faulted(32, seed=5)
    args["gain"] = np.abs(args["gain"])  # no reversed wheel: the fault-unaware loop stays stable
    working = args["gain"] != 0
    drift = {}
    for dt_s in (0.5, 0.25):
        constants = dataclasses.replace(CONSTANTS, dt_s=dt_s)
        plant = WheelPlant(**args, constants=constants)
        h0 = _inertial_momentum((plant.sigma, plant.omega_rad_s, plant.wheel_speed_rad_s), plant.mass)
        for k in range(round(200.0 / dt_s)):
            command = pd_command(plant.sigma, plant.omega_rad_s, plant.wheel_speed_rad_s, working)
            plant.step(k, command)
        h1 = _inertial_momentum((plant.sigma, plant.omega_rad_s, plant.wheel_speed_rad_s), plant.mass)
        drift[dt_s] = np.abs(h1 - h0).max()
    assert drift[0.5] < 2e-7
    assert drift[0.5] / drift[0.25] > 10.0, drift


def _integrate(args, motor, coulomb, mass, dt_s, duration_s):
    state = (args["sigma0"], args["omega0_rad_s"], args["wheel_speed0_rad_s"])
    for _ in range(round(duration_s / dt_s)):
        state = rk4_step(*state, motor, coulomb, mass, CONSTANTS, dt_s)
    return np.concatenate(state, axis=1)


def test_rk4_is_fourth_order():
    # Smooth conditions (friction's kink at +-wLC and the saturation switch are not): wheels
    # stay between 100 and 560 rad/s, hub rates up to 0.3 rad/s make the error measurable.
    rng = np.random.default_rng(6)
    args = healthy(8, seed=6)
    args["sigma0"] *= 0.2  # stay clear of the shadow switch
    args["omega0_rad_s"] = rng.uniform(-0.3, 0.3, (8, 3))
    args["wheel_speed0_rad_s"] = rng.choice([-1.0, 1.0], (8, 4)) * rng.uniform(250.0, 400.0, (8, 4))
    motor = rng.uniform(-0.05, 0.05, (8, 4))
    coulomb = np.full((8, 4), 10 * CONSTANTS.coulomb_nm)
    mass = MassProperties.of(CONSTANTS, args["inertia_scale"])
    reference = _integrate(args, motor, coulomb, mass, 0.5 / 16, 10.0)
    assert np.all(np.abs(reference[:, 6:]) > 100.0) and np.all(np.abs(reference[:, 6:]) < 0.9 * OMEGA_MAX)
    err = [np.abs(_integrate(args, motor, coulomb, mass, dt, 10.0) - reference).max() for dt in (0.5, 0.25)]
    assert 2.0**3.5 < err[0] / err[1] < 2.0**4.5, err


def test_motor_torque_clip_and_speed_saturation():
    at = OMEGA_MAX
    speed = np.array([[at, at, -at, -at, 1.03 * at, 1.03 * at, 0.999 * at, at]])
    command = np.array([[1.0, -1.0, -1.0, 1.0, 0.4, -0.4, 1.0, 0.0]])
    u = motor_torque_nm(command, np.ones((1, 8)), np.zeros((1, 8)), speed, U_MAX, OMEGA_MAX)
    # pushed further: nothing; pushed back: full torque; below the limit: full torque
    np.testing.assert_array_equal(u, [[0.0, -U_MAX, 0.0, U_MAX, 0.0, -0.4 * U_MAX, U_MAX, 0.0]])
    # the fault acts before the clip: (g a + b) u_max, then +-u_max
    u = motor_torque_nm(
        np.array([[1.0, 1.0, -0.5, 0.2]]),
        np.array([[1.5, -0.3, 2.0, 0.0]]),
        np.array([[0.0, 0.2, -0.3, 0.25]]),
        np.zeros((1, 4)),
        U_MAX,
        OMEGA_MAX,
    )
    np.testing.assert_allclose(u, [[U_MAX, -0.1 * U_MAX, -U_MAX, 0.25 * U_MAX]], rtol=1e-15)


def test_a_wheel_at_the_speed_limit_gets_no_torque_until_pushed_back():
    args = healthy(1, seed=7)
    args["wheel_speed0_rad_s"][0] = [0.999 * OMEGA_MAX, 100.0, -100.0, 50.0]
    plant = WheelPlant(**args)
    speeds, applied = [], []
    push = np.array([[1.0, 0.0, 0.0, 0.0]])
    for k in range(400):
        speeds.append(plant.wheel_speed_rad_s[0, 0])
        plant.step(k, push)
        applied.append(plant.applied_torque_nm[0, 0])
    speeds, applied = np.array(speeds), np.array(applied)
    at_limit = speeds >= OMEGA_MAX
    # one push overshoots the limit by ~u_max dt / Js = 16 rad/s; friction takes ~190 steps to bring
    # the wheel back under it, then the next push overshoots again
    assert at_limit.sum() > 300 and (~at_limit).sum() >= 2
    np.testing.assert_array_equal(applied[at_limit], 0.0)
    np.testing.assert_array_equal(applied[~at_limit], U_MAX)
    assert OMEGA_MAX < speeds.max() < 1.05 * OMEGA_MAX  # overshoot within the step, as the v2 definition says
    start = plant.wheel_speed_rad_s[0, 0]
    plant.step(400, -push)  # pushed back from the limit: full torque, the wheel slows down
    assert plant.applied_torque_nm[0, 0] == -U_MAX and plant.wheel_speed_rad_s[0, 0] < start - 10.0


def test_friction_opposes_speed_and_is_linear_inside_the_zone():
    fc = CONSTANTS.coulomb_nm
    speed = np.array([[-100.0, -3.0, -1.5, 0.0, 1.5, 3.0, 100.0, 2.999999]])
    coulomb = np.full_like(speed, fc)
    fr = friction_torque_nm(speed, coulomb, 0.0, 3.0)
    np.testing.assert_allclose(fr, [[fc, fc, fc / 2, 0.0, -fc / 2, -fc, -fc, -fc * 2.999999 / 3]], rtol=1e-15)
    # viscous term and per-wheel Coulomb (a fault multiplies one wheel's)
    coulomb[0, 6] = 20 * fc
    fr = friction_torque_nm(speed, coulomb, 1e-6, 3.0)
    assert fr[0, 6] == pytest.approx(-(20 * fc + 1e-6 * 100.0), rel=1e-15)
    assert fr[0, 4] == pytest.approx(-(fc + 3e-6) / 3.0 * 1.5, rel=1e-15)
    assert fr[0, 0] == pytest.approx(fc + 1e-4, rel=1e-15)


@pytest.mark.parametrize("multiplier", [1.0, 60.0])
def test_friction_brakes_a_coasting_wheel_to_rest_without_chattering(multiplier):
    # The wide linear zone is what makes this hold at dt = 0.5 s: inside it the wheel decays
    # exponentially (time constant Js wLC / fC = 19 s nominal, 0.32 s at 60x: RK4's factor per
    # step is still 0.27 > 0), so the speed never changes sign. The hub starts at rest and takes
    # the wheel's momentum; its slow nutation keeps the wheel's relative speed at a ~1e-8 rad/s
    # floor at 60x (Js g . w_dot balanced by friction), so "decreasing" is checked above that.
    args = healthy(1, seed=8)
    args["omega0_rad_s"][0] = 0.0
    args["wheel_speed0_rad_s"][0] = [5.0, 0.0, 0.0, 0.0]
    args["coulomb_nm"][0, 0] *= multiplier
    plant = WheelPlant(**args)
    speeds = [5.0]
    for k in range(400):
        plant.step(k, np.zeros((1, 4)))
        speeds.append(plant.wheel_speed_rad_s[0, 0])
    speeds = np.array(speeds)
    assert np.all(speeds > 0.0)
    above_floor = speeds[:-1] > 1e-6
    assert above_floor.sum() > 3 and np.all(np.diff(speeds)[above_floor] < 0.0)
    assert speeds[-1] < (1e-3 if multiplier == 1.0 else 1e-6)


def test_faults_apply_from_the_onset_step_and_not_before():
    args = faulted(16, seed=9)
    args["gain"][:, 1], args["bias"][:, 1] = 0.0, 0.0  # every wheel 1 dies at the onset
    args["onset_step"] = np.full(16, 10)
    clean = {**args, "gain": np.ones((16, 4)), "bias": np.zeros((16, 4))}
    clean["coulomb_nm"] = np.full((16, 4), CONSTANTS.coulomb_nm)
    plant, healthy_plant = WheelPlant(**args), WheelPlant(**clean)
    rng = np.random.default_rng(10)
    for k in range(10):  # healthy until step 10: the same plant to the last bit
        command = rng.uniform(-1.0, 1.0, (16, 4))
        np.testing.assert_array_equal(plant.step(k, command), healthy_plant.step(k, command))
        np.testing.assert_array_equal(plant.wheel_speed_rad_s, healthy_plant.wheel_speed_rad_s)
    command = rng.uniform(-1.0, 1.0, (16, 4))
    speeds = plant.wheel_speed_rad_s.copy()
    plant.step(10, command)
    expected = np.clip((args["gain"] * command + args["bias"]) * U_MAX, -U_MAX, U_MAX)
    expected[(np.abs(speeds) >= OMEGA_MAX) & (speeds * expected >= 0)] = 0.0
    np.testing.assert_array_equal(plant.applied_torque_nm, expected)
    healthy_plant.step(10, command)
    assert np.all(plant.applied_torque_nm[:, 1] == 0.0) and np.any(healthy_plant.applied_torque_nm[:, 1] != 0)
    assert np.all(np.any(plant.wheel_speed_rad_s != healthy_plant.wheel_speed_rad_s, axis=1))


def test_a_friction_fault_changes_nothing_before_its_onset():
    args = healthy(4, seed=11)
    faulty = {**args, "coulomb_nm": args["coulomb_nm"] * 20.0, "onset_step": np.full(4, 30)}
    a, b = WheelPlant(**args), WheelPlant(**faulty)
    zero = np.zeros((4, 4))
    for k in range(30):
        a.step(k, zero), b.step(k, zero)
    np.testing.assert_array_equal(a.wheel_speed_rad_s, b.wheel_speed_rad_s)
    a.step(30, zero), b.step(30, zero)
    slower = np.abs(b.wheel_speed_rad_s) < np.abs(a.wheel_speed_rad_s)
    assert slower.all()  # 20x friction from the onset on brakes every wheel harder


def test_a_dead_wheel_applies_no_motor_torque():
    args = faulted(8, seed=12)
    args["gain"][:, 3], args["bias"][:, 3], args["onset_step"][:] = 0.0, 0.0, 0
    plant = WheelPlant(**args)
    rng = np.random.default_rng(13)
    for k in range(50):
        plant.step(k, rng.choice([-1.0, 1.0], (8, 4)))
        np.testing.assert_array_equal(plant.applied_torque_nm[:, 3], 0.0)
        assert np.all(np.abs(plant.applied_torque_nm[:, :3]).max(axis=1) > 0.0)


def test_shadow_switch_keeps_sigma_in_the_unit_ball_and_the_attitude():
    args = healthy(64, seed=14)
    args["omega0_rad_s"] = np.random.default_rng(15).uniform(-0.3, 0.3, (64, 3))  # tumbles
    plant = WheelPlant(**args, constants=FRICTIONLESS)
    mass = plant.mass
    h0 = _inertial_momentum((plant.sigma, plant.omega_rad_s, plant.wheel_speed_rad_s), mass, FRICTIONLESS)
    switches = 0
    for k in range(100):
        before = plant.sigma.copy()
        s2 = plant.step(k, np.zeros((64, 4)))
        np.testing.assert_array_equal(s2, norm2(plant.sigma))
        assert np.all(s2 <= 1.0)
        switches += int(np.sum(np.einsum("ij,ij->i", before, plant.sigma) < 0.0))
    assert switches > 10
    # The switch relabels the attitude, it does not move it: momentum stays put in inertial space.
    # A wrong switch would move H_N by O(|H|) ~ 1; RK4's truncation at |w| dt ~ 0.15 rad per step
    # is what remains (measured 3.2e-5 N m s after 100 steps).
    h1 = _inertial_momentum((plant.sigma, plant.omega_rad_s, plant.wheel_speed_rad_s), mass, FRICTIONLESS)
    assert np.abs(h0).max() > 1.0
    np.testing.assert_allclose(h1, h0, rtol=0, atol=1e-4)


def test_inputs_are_checked_and_copied():
    args = healthy(3, seed=16)
    plant = WheelPlant(**args)
    plant.step(0, np.zeros((3, 4)))
    assert not np.shares_memory(plant.sigma, args["sigma0"])
    with pytest.raises(ValueError, match="command"):
        plant.step(1, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="wheel_speed0_rad_s"):
        WheelPlant(**{**args, "wheel_speed0_rad_s": np.zeros((3, 3))})
    with pytest.raises(ValueError, match="inertia_scale"):
        WheelPlant(**{**args, "inertia_scale": np.zeros(3)})
