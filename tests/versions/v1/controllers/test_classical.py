"""The classical battery: each law does what its literature says on scripted faults, and its
tuning touches the train split only and is deterministic for a seed."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

import scftc_cli.baselines.params as params_module
from scftc_cli.errors import ScftcError
from scftc_cli.protocol import Progress
from scftc_cli.sim.mrp import principal_angle_deg
from scftc_cli.sim.rollout import rollout
from scftc_cli.training import TrainRequest, tuning
from scftc_cli.versions.v1.controllers.adaptive import AdaptiveParams, ClassicalAdaptive
from scftc_cli.versions.v1.controllers.icl import ICLAdaptive, ICLParams
from scftc_cli.versions.v1.controllers.nussbaum import Nussbaum, NussbaumParams
from scftc_cli.versions.v1.controllers.observer import DisturbanceObserver, measured_torque
from scftc_cli.versions.v1.controllers.pid import PID, PIDParams
from scftc_cli.versions.v1.controllers.rls import RLSDob, RLSParams
from scftc_cli.versions.v1.sim.faults import ActuatorFault, RigidEpisodes
from scftc_cli.versions.v1.sim.testbed import TESTBED, public_context
from scftc_cli.versions.v1.spec import V1 as SPEC
from scftc_cli.versions.v1.training import tuning as v1_tuning


def scripted(gain, bias=(0.0, 0.0, 0.0), scale=1.0, sigma0=None, omega0=None, n=4, seed=0) -> RigidEpisodes:
    """``n`` episodes of one hand-made fault; random (seeded) initial conditions unless given."""
    rng = np.random.default_rng(seed)
    sigma0 = rng.uniform(-0.5, 0.5, (n, 3)) if sigma0 is None else np.tile(sigma0, (n, 1))
    omega0 = rng.uniform(-0.02, 0.02, (n, 3)) if omega0 is None else np.tile(omega0, (n, 1))
    fault = ActuatorFault(
        np.tile(np.asarray(gain, float), (n, 1)), np.tile(np.asarray(bias, float), (n, 1)), np.full(n, scale)
    )
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


class _Recorder(Progress):
    def __init__(self, controller, attribute) -> None:
        self.controller, self.attribute, self.history = controller, attribute, []

    def advance(self, amount: float = 1.0) -> None:
        self.history.append(np.copy(self.attribute(self.controller)))


def trace(controller, episodes: RigidEpisodes, attribute):
    """Fly ``episodes`` and record ``attribute(controller)`` after every step: ``(steps, ...)``."""
    recorder = _Recorder(controller, attribute)
    result = rollout(controller, episodes, progress=recorder)
    return result, np.stack(recorder.history)


# --- measured torque and observer ----------------------------------------------------------------


def test_measured_torque_recovers_theta_a_plus_beta():
    episodes = scripted(gain=(0.7, -1.3, 0.5), bias=(0.1, -0.15, 0.05), scale=1.6)
    result = rollout(RLSDob(RLSParams()), episodes, record=True)
    context = public_context(episodes.n)
    omega = result.omega_rad_s
    dw = np.stack([measured_torque(omega[:, k], omega[:, k + 1], context) for k in range(40)], axis=1)
    expected = episodes.fault.theta[:, None] * result.commands[:, :40] + episodes.fault.beta[:, None]
    assert np.max(np.abs(dw - expected)) < 1e-3  # trapezoid gyroscopic term: ~1e-4 at these rates


def test_observer_cancels_the_bias_even_with_a_wrong_gain_estimate():
    theta, beta, theta_hat = 0.4, 0.15, 0.7  # gain overestimated by 75 %
    observer = DisturbanceObserver(1, gain=0.1)
    a = np.zeros((1, 3))
    for _ in range(300):  # at rest: the command holds the axis, a = -beta_hat / theta_hat
        a = np.full((1, 3), -observer.beta_hat[0, 0] / theta_hat)
        observer.update(theta * a + beta, a, np.full((1, 3), theta_hat))
    assert theta * a[0, 0] + beta == pytest.approx(0.0, abs=1e-6)  # net torque cancelled


# --- classical adaptive: sign identification -----------------------------------------------------


@pytest.mark.parametrize("tuned", [False, True], ids=["starting-values", "tuned"])
def test_classical_adaptive_flips_a_reversed_axis_quickly_and_never_back(tuned):
    episodes = scripted(gain=(1.0, -1.0, 1.0), n=8)
    controller = ClassicalAdaptive() if tuned else ClassicalAdaptive(AdaptiveParams())
    result, signs = trace(controller, episodes, lambda c: c.vote.sign)  # (steps, n, 3)
    reversed_axis = signs[:, :, 1]
    assert np.all(reversed_axis[20:] == -1.0), "the reversed axis must be identified within 20 steps"
    flips = np.count_nonzero(np.diff(reversed_axis, axis=0), axis=0)
    assert np.all(flips == 1), "exactly one flip, never back"
    assert np.all(signs[:, :, [0, 2]] == 1.0), "healthy axes are never flipped"
    assert np.all(result.dwell_max_error_deg <= SPEC.gates.settled_deg)


def test_classical_adaptive_sign_vote_ignores_a_constant_bias():
    episodes = scripted(gain=(-0.8, 0.9, 1.2), bias=(0.18, -0.18, 0.18), n=6)
    _, signs = trace(ClassicalAdaptive(AdaptiveParams()), episodes, lambda c: c.vote.sign)
    assert np.all(signs[20:, :, 0] == -1.0) and np.all(signs[:, :, 1:] == 1.0)


# --- Nussbaum --------------------------------------------------------------------------------------


def test_nussbaum_drives_a_reversed_single_axis_to_zero_error():
    episodes = scripted(gain=(-1.0, 1.0, 1.0), sigma0=(0.3, 0.0, 0.0), omega0=(0.0, 0.0, 0.0), n=1)
    controller = Nussbaum(NussbaumParams(gamma=0.2, zeta0=1.0, dead_zone=0.01))
    result, zeta = trace(controller, episodes, lambda c: c.zeta)
    assert zeta[-1, 0, 0] > np.pi / 2, "the gain must have swept through a sign change"
    assert zeta[-1, 0, 1] == zeta[0, 0, 1], "an axis at rest never adapts (dead-zone)"
    assert result.final_error_deg[0] < 0.05
    assert result.final_error_deg[0] < 0.01 * principal_angle_deg(episodes.sigma0)[0]


# --- ICL -------------------------------------------------------------------------------------------


def test_icl_estimates_a_constant_gain_within_five_percent_given_exciting_data():
    episodes = scripted(gain=(0.6, -1.4, 0.9), bias=(0.1, 0.0, -0.12), scale=1.2, n=4)
    params = ICLParams(window=2, stack_size=10, gamma_cl=1.0, dither_amp=0.4, dither_steps=40)
    controller = ICLAdaptive(params)
    rollout(controller, episodes)
    theta = episodes.fault.theta
    assert np.max(np.abs(controller.theta_hat - theta) / np.abs(theta)) < 0.05
    assert np.max(np.abs(controller.beta_hat - episodes.fault.beta)) < 0.01


def test_icl_history_stack_keeps_the_most_exciting_windows():
    from scftc_cli.versions.v1.controllers.icl import HistoryStack, eig2

    stack = HistoryStack(1, 3, replace_margin=1.0)
    for y1 in (0.9, 0.9, 0.9):  # collinear, nearly singular
        stack.offer(np.full((1, 3), y1), np.full((1, 3), 0.5 * y1))
    before, _ = eig2(*stack.info())
    stack.offer(np.full((1, 3), -0.8), np.full((1, 3), -0.4))
    after, _ = eig2(*stack.info())
    assert np.all(after > before + 0.5)


# --- PID -------------------------------------------------------------------------------------------


def test_pid_integrator_stays_bounded_against_a_saturated_actuator():
    # bias beyond the axis' authority: the actuator saturates and the error never closes
    episodes = scripted(gain=(0.5, 1.0, 1.0), bias=(0.8, 0.0, 0.0), n=4)
    params = PIDParams(kp_s2=0.04, kd_s=0.14, ki_s3=0.002, integral_cap=0.3, integrate_below=1.0)
    controller = PID(params)
    result, z = trace(controller, episodes, lambda c: c.z)
    authority = np.abs(z) * params.ki_s3 * np.asarray(SPEC.plant.inertia_nominal_kgm2) / SPEC.plant.tau_max_nm
    assert np.all(authority <= params.integral_cap + 1e-12)
    assert np.all(np.isfinite(z))
    assert np.all(result.final_error_deg > 1.0)  # the fault is beyond reach; winding up would not help


def test_pid_freezes_integration_while_saturated_and_pushing():
    controller = PID(PIDParams(ki_s3=0.001, integral_cap=1.0, integrate_below=1.0))
    controller.reset(1, public_context(1))
    controller.act(np.array([[0.4, 0.0, 0.0, 0.1, 0.0, 0.0]]))  # u << -1 on axis 0, sigma > 0
    assert controller.z[0, 0] == 0.0
    controller.act(np.array([[0.01, 0.0, 0.0, 0.0, 0.0, 0.0]]))  # unsaturated: integrates
    assert controller.z[0, 0] == pytest.approx(0.5 * 0.01)


# --- params files ----------------------------------------------------------------------------------


@pytest.mark.parametrize("cls", [PID, ClassicalAdaptive, ICLAdaptive, Nussbaum, RLSDob])
def test_a_missing_params_file_raises_instead_of_running_untuned(cls, tmp_path, monkeypatch):
    moved = dataclasses.replace(params_module.get_version("scftc-v1"), folder=tmp_path)
    monkeypatch.setattr(params_module, "get_version", lambda _name: moved)
    with pytest.raises(ScftcError, match="scftc train --controller"):
        cls()


# --- tuning ----------------------------------------------------------------------------------------


def test_tuning_samples_train_faults_only_and_is_deterministic(tmp_path, monkeypatch):
    seen: list[RigidEpisodes] = []
    original = TESTBED.draw

    def recording(split, fault_class, *args, **kwargs):
        episodes = original(split, fault_class, *args, **kwargs)
        seen.append(episodes)
        return episodes

    monkeypatch.setattr(TESTBED, "draw", recording)  # every door to the episodes: tuning and scoring
    outputs = []
    for i in range(2):
        request = TrainRequest(controller="nussbaum", seed=3, budget="quick", out=tmp_path / f"n{i}.yaml")
        report = tuning.tune(v1_tuning.SPECS["nussbaum"], request)
        outputs.append(yaml.safe_load(report.artifact.read_text()))

    assert seen and {e.split for e in seen} == {"train"}
    train = SPEC.splits["train"]
    for episodes in seen:
        fault = episodes.fault
        assert np.all(train.inertia_scale.contains(fault.inertia_scale))
        assert np.all(np.sum(fault.gain < 0, axis=1) <= max(train.reversed_axes))
        alive = fault.gain != 0
        assert np.all(train.gain_magnitude.contains(np.abs(fault.gain[alive])))
        assert np.all(train.bias.contains(fault.bias))
    assert outputs[0]["params"] == outputs[1]["params"]
    assert outputs[0]["provenance"]["train_settled_rate"] == outputs[1]["provenance"]["train_settled_rate"]
    assert outputs[0]["provenance"]["seed"] == 3 and outputs[0]["provenance"]["budget"] == "quick"
