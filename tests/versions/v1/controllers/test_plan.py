"""``rls_plan``: the geometry of the p-q-p plan, the rest-to-rest slew, the gyroscopic nulling of a
dead axis' rate, and the closed loop on train episodes and hand-made faults."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.protocol import Progress
from scftc_cli.registry import make_controller
from scftc_cli.sim.mrp import axis_mrp, compose, euler_pqp, principal_angle_deg, to_dcm, twist_swing, wrap
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v1.controllers.analytic import BiasOracle
from scftc_cli.versions.v1.controllers.plan import (
    ANALYTIC,
    HOLD,
    NULL_RATE,
    SLEW,
    PlanParams,
    RLSPlan,
    plan_slews,
    ptos_accel,
    slew_time,
)
from scftc_cli.versions.v1.controllers.rls import RLSDob
from scftc_cli.versions.v1.sim.faults import ActuatorFault, RigidEpisodes
from scftc_cli.versions.v1.sim.testbed import TESTBED
from scftc_cli.versions.v1.spec import V1 as SPEC

DT = SPEC.dt_s


def scripted(theta, beta=None, sigma0=None, omega0=None, n=4, seed=0) -> RigidEpisodes:
    """``n`` episodes of one hand-made fault ``(theta, beta)`` (``f = 1``); seeded random initial
    conditions (the benchmark's ranges) unless given."""
    rng = np.random.default_rng(seed)
    sigma0 = rng.uniform(-0.5, 0.5, (n, 3)) if sigma0 is None else np.tile(sigma0, (n, 1))
    omega0 = rng.uniform(-0.02, 0.02, (n, 3)) if omega0 is None else np.tile(omega0, (n, 1))
    beta = np.zeros(3) if beta is None else beta
    gain = np.broadcast_to(np.asarray(theta, float), (n, 3)).copy()
    bias = np.broadcast_to(np.asarray(beta, float), (n, 3)).copy()
    fault = ActuatorFault(gain, bias, np.ones(n))
    return scripted_episodes(fault, sigma0, omega0)


def scripted_episodes(fault: ActuatorFault, sigma0: np.ndarray, omega0: np.ndarray) -> RigidEpisodes:
    n = len(sigma0)
    return RigidEpisodes(
        benchmark=SPEC.version,
        split="train",
        fault_class="scripted",
        sensor=None,
        fault_index=np.zeros(n, int),
        seed_index=np.arange(n),
        fault=fault,
        sigma0=sigma0,
        omega0_rad_s=omega0,
    )


def trace(controller, episodes):
    """Fly ``episodes`` recording the mode of every episode after every step ``(steps, n)``."""

    class Modes(Progress):
        def __init__(self) -> None:
            self.modes: list[np.ndarray] = []

        def advance(self, amount: float = 1.0) -> None:
            self.modes.append(controller.mode.copy())

    modes = Modes()
    result = rollout(controller, episodes, record=True, progress=modes)
    return result, np.stack(modes.modes)


def elementary(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``M_axis(angle)`` ``(m, 3, 3)``: the frame rotation by ``angle`` about body axis ``axis``."""
    return to_dcm(axis_mrp(axis, angle))


# --- geometry ----------------------------------------------------------------------------------


def test_pqp_decomposition_composes_back_to_the_target_rotation():
    rng = np.random.default_rng(1)
    m = 600
    sigma = rng.uniform(-1.0, 1.0, (m, 3))
    sigma[:5] = 0.0  # identity: gimbal lock of the symmetric sequence
    sigma[5:10, :] = 0.0
    sigma[5:10, 1] = 0.3  # pure rotations about one axis: lock for some pairs
    p = rng.integers(0, 3, m)
    q = (p + rng.integers(1, 3, m)) % 3
    target_from_body = np.transpose(to_dcm(sigma), (0, 2, 1))
    angles = euler_pqp(target_from_body, p, q)
    for branch in range(2):
        a, b, c = angles[:, branch].T
        assert np.all(np.abs(angles[:, branch]) <= np.pi + 1e-12)
        rebuilt = elementary(p, c) @ elementary(q, b) @ elementary(p, a)
        assert np.max(np.abs(rebuilt - target_from_body)) < 1e-12
        # flying the three body rotations from sigma lands on the target
        end = compose(compose(compose(sigma, axis_mrp(p, a)), axis_mrp(q, b)), axis_mrp(p, c))
        assert np.max(principal_angle_deg(end)) < 1e-9


def test_planner_picks_the_shortest_order_and_branch():
    rng = np.random.default_rng(2)
    m = 200
    sigma = rng.uniform(-0.5, 0.5, (m, 3))
    live = np.tile([1, 2], (m, 1))
    a_pos = np.tile([0.0, 0.004, 0.03], (m, 1))  # axis 1 slow, axis 2 fast
    axes, angles, t = plan_slews(sigma, live, a_pos, a_pos, 0.9, 0.0)
    rows = np.arange(m)
    for order in ((1, 2), (2, 1)):
        p, q = np.full(m, order[0]), np.full(m, order[1])
        for branch in euler_pqp(np.transpose(to_dcm(sigma), (0, 2, 1)), p, q).transpose(1, 0, 2):
            acc = a_pos[rows[:, None], np.stack([p, q, p], 1)]
            assert np.all(t <= np.sum(slew_time(branch, acc, acc, 0.9), axis=1) + 1e-9)
    # the slow axis is used once (the middle slew) whenever that is possible
    assert np.mean(axes[:, 1] == 1) > 0.9
    assert np.all(np.abs(wrap(angles)) <= np.pi)


def test_twist_swing_splits_a_rotation_into_twist_about_the_axis_and_a_perpendicular_swing():
    rng = np.random.default_rng(3)
    m = 300
    axis = rng.integers(0, 3, m)
    psi0 = rng.uniform(-np.pi, np.pi, m)
    swing = rng.normal(0.0, 1e-3, (m, 3))
    swing[np.arange(m), axis] = 0.0
    sigma_rel = compose(axis_mrp(axis, psi0), np.tan(np.linalg.norm(swing, axis=1) / 4)[:, None] * swing
                        / np.maximum(np.linalg.norm(swing, axis=1), 1e-300)[:, None])  # fmt: skip
    psi, delta = twist_swing(sigma_rel, axis)
    assert np.max(np.abs(wrap(psi - psi0))) < 1e-12
    assert np.max(np.abs(delta - swing)) < 1e-12


# --- rest-to-rest slew -----------------------------------------------------------------------------


@pytest.mark.parametrize("alpha", [0.0025, 0.012, 0.09])
@pytest.mark.parametrize("angle", [0.003, 0.7, np.pi])
def test_slew_ends_at_rest_at_the_planned_time_without_overshoot(alpha, angle):
    # exact zero-order-hold double integrator, the error starting at -angle (rotate by +angle)
    e, v = np.array([-angle]), np.array([0.0])
    a = np.array([alpha])
    errors = []
    for _ in range(400):
        u = ptos_accel(e, v, a, a, 0.85, 0.3, DT)
        assert abs(u[0]) <= alpha + 1e-15
        e, v = e + v * DT + 0.5 * u * DT**2, v + u * DT
        errors.append((e[0], v[0]))
    errors = np.array(errors)
    at_rest = (np.abs(errors[:, 0]) < 1e-4) & (np.abs(errors[:, 1]) < 2e-5)
    done = (np.argmax(at_rest) + 1) * DT
    assert at_rest[np.argmax(at_rest) :].all(), "stays at rest once there"
    predicted = slew_time(np.array([angle]), a, a, 0.85)[0]
    # the bang-bang part takes the planned time; the linear tail adds a few steps
    assert 0.9 * predicted <= done + DT and done <= predicted + 5.0
    assert np.max(errors[:, 0]) < 1e-6, "never overshoots"


# --- phase 0: the dead axis' rate through the gyroscopic coupling ----------------------------------


@pytest.mark.parametrize("dead", [0, 1, 2])
def test_phase0_drives_the_dead_axis_rate_to_zero(dead):
    theta = np.full(3, 0.5)
    theta[dead] = 0.0
    omega0 = np.zeros(3)
    omega0[dead] = 0.02
    episodes = scripted(theta, sigma0=np.array([0.1, -0.2, 0.15]), omega0=omega0, n=1)
    controller = RLSPlan(PlanParams())
    result, modes = trace(controller, episodes)
    assert controller.held[0] == dead and not controller.held_live[0]
    nulling = np.nonzero(modes[:, 0] == NULL_RATE)[0]
    start, end = nulling[0], nulling[-1] + 1  # omega index k + 1 is the state after step k
    w_dead = result.omega_rad_s[0, :, dead]
    assert abs(w_dead[start]) > 0.015
    assert abs(w_dead[end + 1]) < controller.params.tol_dead_rate
    assert (end - start) * DT < 45.0  # the product maneuver of a 0.02 rad/s rate at theta = 0.5: ~20-35 s
    # the dead rate stays nulled through the slews
    assert np.max(np.abs(w_dead[end + 1 :])) < 1e-5
    assert result.dwell_max_error_deg[0] <= SPEC.gates.settled_deg


# --- closed loop ------------------------------------------------------------------------------------


def test_settles_train_loss_episodes_on_the_predicted_schedule():
    episodes = TESTBED.draw("train", "loss", n_faults=3, n_seeds=2)
    controller = make_controller("rls_plan")
    result, modes = trace(controller, episodes)
    dead = np.argmax(episodes.fault.gain == 0, axis=1)
    assert np.array_equal(controller.held, dead) and not controller.held_live.any()
    assert np.all(np.argmax(modes != ANALYTIC, axis=0) <= 10), "the dead axis is found within 5 s"
    assert np.all(result.dwell_max_error_deg <= SPEC.gates.settled_deg)
    # the three slews take about what the plan predicted from the identified authorities
    flying = np.sum((modes == SLEW), axis=0) * DT
    assert np.all(np.abs(flying - controller.plan_time) < 0.15 * controller.plan_time + 5.0)
    assert np.all(modes[-1] == HOLD)


def test_no_regression_on_sign_and_gain_it_flies_the_rls_dob_law():
    for fault_class in ("sign", "gain"):
        episodes = TESTBED.draw("train", fault_class, n_faults=3, n_seeds=2)
        ours = rollout(make_controller("rls_plan"), episodes, record=True)
        theirs = rollout(RLSDob(), episodes, record=True)
        assert np.array_equal(ours.commands, theirs.commands)
        assert np.all(ours.dwell_max_error_deg <= SPEC.gates.settled_deg)


def test_low_margin_bias_plan_settles_where_the_pd_bias_oracle_does_not():
    # one axis with |theta| - |beta| = 0.02 (the corner where the oracle's PD law is too slow)
    rng = np.random.default_rng(5)
    n = 12
    theta = rng.uniform(0.5, 1.0, (n, 3)) * rng.choice([-1.0, 1.0], (n, 3))
    beta = rng.uniform(-0.2, 0.2, (n, 3))
    weak = rng.integers(0, 3, n)
    rows = np.arange(n)
    theta[rows, weak] = 0.15 * np.sign(theta[rows, weak])
    beta[rows, weak] = 0.13 * rng.choice([-1.0, 1.0], n)
    fault = ActuatorFault(theta, beta, np.ones(n))
    episodes = scripted_episodes(fault, rng.uniform(-0.5, 0.5, (n, 3)), rng.uniform(-0.02, 0.02, (n, 3)))
    plan = RLSPlan(PlanParams())
    ours = rollout(plan, episodes).dwell_max_error_deg <= SPEC.gates.settled_deg
    oracle = rollout(BiasOracle(), episodes).dwell_max_error_deg <= SPEC.gates.settled_deg
    assert np.array_equal(plan.held, weak) and plan.held_live.all()
    assert ours.sum() == n
    assert oracle.sum() <= n - 2
