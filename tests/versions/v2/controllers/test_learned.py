"""scftc-v2's learned battery: rma_student, rma_dob and e2e_ppo (numba inference, no torch at
evaluation), the wheel measurement they build on, and the change test that re-opens a latch."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from scftc_cli.baselines import recurrent
from scftc_cli.baselines.checker import check_controller
from scftc_cli.baselines.policy import PolicyConfig
from scftc_cli.protocol import Context
from scftc_cli.registry import make_controller
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v2 import VERSION
from scftc_cli.versions.v2.controllers.latch import CusumDetector
from scftc_cli.versions.v2.controllers.observer import OffsetObserver
from scftc_cli.versions.v2.controllers.ppo import E2EPPO
from scftc_cli.versions.v2.controllers.rma import StudentController, student_effective_gain
from scftc_cli.versions.v2.controllers.student import (
    N_FEATURES,
    DetectorConfig,
    ObserverConfig,
    StudentConfig,
    load_student,
)
from scftc_cli.versions.v2.sim.faults import SensorFault, WheelEpisodes, WheelFault
from scftc_cli.versions.v2.sim.testbed import TESTBED, public_context
from scftc_cli.versions.v2.spec import V2
from tests.versions.committed import check_committed_weights

V = V2.version
LEARNED = ("rma_student", "rma_dob", "e2e_ppo")
STUDENTS = ("rma_student", "rma_dob")
# Train cells flown to record inputs: every actuator class and a sensor fault.
CELLS = (
    ("sign", None),
    ("gain", None),
    ("gain_bias", None),
    ("friction", None),
    ("loss", None),
    ("sign", "st_outage"),
)
# numba (float64) against torch run in float64 on the same weights: relative over each sequence.
RTOL = 1e-10


def relative_error(got: np.ndarray, ref: np.ndarray, axis: int | tuple[int, ...]) -> float:
    """The largest over sequences of ``max |got - ref| / max |ref|`` along ``axis``."""
    scale = np.maximum(np.max(np.abs(ref), axis=axis), 1e-300)
    return float(np.max(np.max(np.abs(got - ref), axis=axis) / scale))


class _Recording(StudentController):
    """The deployed student controller, keeping what the estimator did at every step."""

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        self.features: list[np.ndarray] = []
        self.restarts: list[np.ndarray] = []
        self.active: list[np.ndarray] = []
        self.raw: list[np.ndarray] = []
        self.gains: list[np.ndarray] = []
        self.latched: list[np.ndarray] = []
        self.alarms: list[np.ndarray] = []

    def gain_hat(self, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        gain = super().gain_hat(gyro, tach)
        est = self.estimator
        self.features.append(est.features.copy())
        self.restarts.append(est.restarted.copy())
        self.active.append(est.active.copy())
        self.raw.append(est.raw.copy())
        self.gains.append(gain.copy())
        self.latched.append(est.latched.copy())
        self.alarms.append(est.alarms.copy())
        return gain


# ---------------------------------------------------------------------------------------------
# Committed artifacts and the protocol


@pytest.mark.parametrize("name", LEARNED)
def test_committed_weights_load_with_provenance(name: str) -> None:
    check_committed_weights(V, name)


@pytest.mark.parametrize("name", LEARNED)
def test_protocol_checker_passes(name: str) -> None:
    check_controller(make_controller(name, V), benchmark=V, classes=("gain_bias", "friction", "loss"))


@pytest.mark.parametrize("name", LEARNED)
def test_a_v1_context_is_refused_with_a_clear_error(name: str) -> None:
    from scftc_cli.errors import UsageError
    from scftc_cli.versions.v1.sim.testbed import public_context as v1_context

    with pytest.raises(UsageError, match="reaction wheels"):
        make_controller(name, V).reset(2, v1_context(2))


def test_evaluation_needs_no_torch() -> None:
    script = textwrap.dedent(
        f"""
        import sys
        sys.modules["torch"] = None  # any `import torch` now raises ImportError
        from scftc_cli.evaluate import Cell, evaluate_cell
        from scftc_cli.registry import make_controller
        from scftc_cli.versions.v2.spec import V2

        for name in {LEARNED!r}:
            cell = Cell("train", "gain_bias")
            run = evaluate_cell(lambda _c: make_controller(name, "{V}"), V2, cell, n_faults=2, n_seeds=1)
            assert run.result.n == 2
        assert sys.modules["torch"] is None
        print("ok")
        """
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr


# ---------------------------------------------------------------------------------------------
# The kernels against the torch modules they were trained as, on recorded closed-loop inputs


def _torch_student(name: str):  # type: ignore[no-untyped-def]
    torch = pytest.importorskip("torch")
    from scftc_cli.training.student import StudentModule
    from scftc_cli.versions.v2.controllers.student import LAYOUT

    arrays, doc = recurrent.load_weights(VERSION.weights_dir / f"{name}.npz")
    config = StudentConfig.from_dict(doc)
    model = StudentModule(LAYOUT, config.hidden, config.bias_invariant)
    model.load_state_dict({k: torch.from_numpy(v) for k, v in arrays.items()})
    return model.double().eval()


@pytest.mark.parametrize("name", STUDENTS)
def test_student_kernel_matches_torch_on_recorded_rollouts(name: str) -> None:
    torch = pytest.importorskip("torch")
    from scftc_cli.training.dagger import split_segments

    net, config = load_student(name)
    model = _torch_student(name)
    restarts_seen = 0
    for fault_class, sensor in CELLS:
        episodes = TESTBED.draw("train", fault_class, sensor, 3, 2)
        controller = _Recording(net=net, config=config)
        rollout(controller, episodes)
        x = np.stack(controller.features, axis=1)  # (n m, T, F): whole episodes
        restart = np.stack(controller.restarts, axis=1)
        assert x.shape == (episodes.n * 4, V2.steps, N_FEATURES)
        restarts_seen += int(restart.sum())
        mine = net.run(x, restart)  # every step, latched or not
        inside, segments = split_segments(restart, x)
        with torch.no_grad():
            reference = model(torch.from_numpy(segments))[0].numpy()
        # put the segments back in place
        row, start = np.nonzero(np.where(np.arange(V2.steps) == 0, True, restart))
        placed = np.zeros_like(mine)
        for s, (r, k) in enumerate(zip(row, start, strict=True)):
            length = int(inside[s].sum())
            placed[r, k : k + length] = reference[s, :length]
        assert relative_error(mine, placed, axis=1) < RTOL
        # the controller's live estimate is the kernel's wherever the network ran
        active = np.stack(controller.active, axis=1)
        raw = np.stack(controller.raw, axis=1).reshape(episodes.n, V2.steps, 4).transpose(0, 2, 1)
        assert np.array_equal(raw.reshape(-1, V2.steps)[active], mine[active])
    assert restarts_seen > 0  # the restarts are exercised


def test_policy_kernel_matches_torch_on_recorded_rollouts() -> None:
    torch = pytest.importorskip("torch")
    from scftc_cli.training.policy import RecurrentPolicy
    from scftc_cli.versions.v2.controllers.ppo import ACTIONS, OBS_SCALE

    arrays, doc = recurrent.load_weights(VERSION.weights_dir / "e2e_ppo.npz")
    model = RecurrentPolicy(PolicyConfig.from_dict(doc), len(OBS_SCALE), ACTIONS)
    model.load_state_dict({k: torch.from_numpy(v) for k, v in arrays.items()})
    model = model.double().eval()
    net = E2EPPO().net

    class Recording(E2EPPO):
        def act(self, obs: np.ndarray) -> np.ndarray:
            self.inputs.append(self.policy_input(obs, self.prev_action))
            command = super().act(obs)
            self.commands.append(command)
            return command

    for fault_class, sensor in CELLS[:3]:
        controller = Recording(net=net)
        controller.inputs, controller.commands = [], []
        rollout(controller, TESTBED.draw("train", fault_class, sensor, 3, 2))
        u = np.stack(controller.inputs)  # (T, n, 23)
        with torch.no_grad():
            reference = model(torch.from_numpy(u))[0].numpy()  # (T, n, 4)
        state = net.start(u.shape[1])
        mine = np.stack([net.step(u[k], state) for k in range(len(u))])
        assert relative_error(mine, reference, axis=(0, 2)) < RTOL
        assert np.array_equal(np.clip(mine, -1.0, 1.0), np.stack(controller.commands))


# ---------------------------------------------------------------------------------------------
# The measurement, the observer, the allocation guard, the change test


def test_tachometers_measure_each_wheels_realized_torque() -> None:
    # y = Js (dOmega + g . dw) / (u_max dt) - phi0 psi equals the motor's torque (units of u_max)
    # plus the extra friction, to the tachometers' noise, on every step the sample is valid.
    episodes = TESTBED.draw("train", "friction", None, 5, 2)
    net, config = load_student("rma_dob")

    class Measuring(_Recording):
        def reset(self, n: int, context: Context) -> None:
            super().reset(n, context)
            self.samples: list[tuple[np.ndarray, ...]] = []

        def act(self, obs: np.ndarray) -> np.ndarray:
            _, _, gyro, tach = (obs[:, :9], obs[:, 9:12], obs[:, 12:15], obs[:, 15:19])
            meter = self.estimator.meter
            last = None if meter.gyro is None or meter.tach is None else (meter.gyro, meter.tach)
            command = super().act(obs)
            if last is not None:
                self.samples.append((last, gyro.copy(), tach.copy()))
            return command

    controller = Measuring(net=net, config=config)
    result = rollout(controller, episodes, record=True)
    sigma_y = 1.05 * np.sqrt(2.0) * 3.183e-3 * 0.01 / (0.1 * 0.5)
    assert controller.estimator.sigma_y == pytest.approx(sigma_y, rel=1e-3)
    fault, commands = episodes.fault, result.commands
    assert commands is not None
    errors = []
    wheels = controller.wheels
    for k, ((gyro0, tach0), gyro, tach) in enumerate(controller.samples):
        y = wheels.spin_inertia_kgm2 * ((tach - tach0) + (gyro - gyro0) @ wheels.spin_axes.T) / 0.05
        gain, bias, multiplier = fault.at(k)
        motor = np.clip(gain * commands[:, k] + bias, -1.0, 1.0)
        speed = result.states["wheel_speed_rad_s"]
        stable = (np.abs(speed[:, k]) > 4.0) & (np.abs(speed[:, k + 1]) > 4.0)
        stable &= np.sign(speed[:, k]) == np.sign(speed[:, k + 1])
        stable &= np.abs(speed[:, k]) < 0.99 * wheels.omega_max_rad_s  # no torque cut
        friction = -np.sign(speed[:, k]) * multiplier * 5e-4 / 0.1
        errors.append(np.where(stable, y - motor - friction, 0.0))
    assert np.max(np.abs(errors)) < 6 * sigma_y
    assert np.std(np.concatenate(errors)) > 0.5 * sigma_y  # the noise is there: not vacuous


def test_observer_separates_offset_and_friction_once_the_wheel_reverses() -> None:
    rng = np.random.default_rng(3)
    observer = OffsetObserver(ObserverConfig(forgetting=1.0), 1e-3, (1, 1))
    b, d = 0.15, -0.04  # d < 0 cannot happen physically; the observer does not care
    for k in range(200):
        psi = np.array([[1.0 if (k // 25) % 2 else -1.0]])
        residual = b + d * psi + 1e-3 * rng.standard_normal((1, 1))
        observer.update(residual, psi, np.ones((1, 1), dtype=bool))
    assert observer.theta[0, 0] == pytest.approx([b, d], abs=2e-3)


def test_effective_gain_allocates_at_most_one_dead_wheel() -> None:
    gain = np.array([[0.02, -0.05, 1.2, 0.9], [1.0, -0.6, 0.5, 0.0], [0.3, -0.2, 1.0, 1.0]])
    out = student_effective_gain(gain, 0.1)
    assert np.array_equal(out[0], [0.0, -0.1, 1.2, 0.9])  # the weakest is dead, the other kept at 0.1
    assert np.array_equal(out[1], [1.0, -0.6, 0.5, 0.0])
    assert np.array_equal(out[2], gain[2])  # nothing below the threshold


def test_change_test_is_quiet_on_noise_and_fires_on_a_change() -> None:
    rng = np.random.default_rng(0)
    sigma = 9e-4
    detector = CusumDetector(DetectorConfig(), sigma, (200, 4))
    alarms = np.zeros((200, 4), dtype=int)
    for _ in range(400):
        a = rng.uniform(-0.3, 0.3, (200, 4))
        alarms += detector.update(sigma * rng.standard_normal((200, 4)), a, np.ones((200, 4), dtype=bool))
    assert alarms.sum() == 0  # 320 000 samples of pure noise
    # a 30 % gain change under a command of 0.05 fires within a few steps
    fired = []
    for _ in range(10):
        a = np.full((200, 4), 0.05)
        fired.append(
            detector.update(0.3 * a + sigma * rng.standard_normal((200, 4)), a, np.ones((200, 4), bool))
        )
    first = np.argmax(np.stack(fired), axis=0)
    assert np.stack(fired).any(axis=0).all() and first.max() <= 3


def _late_onset_episodes(onset: int) -> WheelEpisodes:
    """Train-range faults (one reversed wheel; gains within [0.5, 1.5]) whose onset is moved to
    ``onset``: the change comes long after every estimate latched on the healthy wheels."""
    base = TESTBED.draw("train", "gain", None, 6, 1)
    gain = np.array(base.fault.gain)
    gain[:, 0] = -np.abs(gain[:, 0])  # wheel 1 reversed in every episode
    fault = WheelFault(
        gain, np.zeros_like(gain), np.ones_like(gain), np.array(base.fault.inertia_scale), np.full(6, onset)
    )
    n = base.n
    return WheelEpisodes(
        benchmark=V,
        split="train",
        fault_class="late-onset",
        sensor=None,
        fault_index=np.arange(n),
        seed_index=np.zeros(n, dtype=np.int64),
        fault=fault,
        sigma0=np.array(base.sigma0),
        omega0_rad_s=np.array(base.omega0_rad_s),
        wheel_speed0_rad_s=np.array(base.wheel_speed0_rad_s),
        sensor_fault=SensorFault(
            np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros((n, 3)), np.zeros((n, 3))
        ),
        noise_seed=np.array(base.noise_seed),
    )


@pytest.mark.parametrize("name", STUDENTS)
def test_a_latch_frozen_on_the_healthy_wheel_reopens_at_a_late_change(name: str) -> None:
    onset = 150  # later than any onset of either split: the test is time-invariant by construction
    episodes = _late_onset_episodes(onset)
    net, config = load_student(name)
    controller = _Recording(net=net, config=config)
    result = rollout(controller, episodes)
    latched, gains = np.stack(controller.latched, axis=1), np.stack(controller.gains, axis=1)
    alarms = np.stack(controller.alarms, axis=1)
    frozen = latched[:, onset - 1]
    assert frozen.mean() >= 0.75  # most wheels latched on the healthy plant before the change
    assert np.allclose(gains[:, onset - 1][frozen], 1.0, atol=0.05)
    fired = alarms[:, onset + 10, 0] > alarms[:, onset - 1, 0]
    assert fired.all()  # the reversed wheel's latch re-opened within 10 steps
    assert np.all(gains[:, -1, 0] < 0.0)  # and was re-identified with its new sign
    # Not asserted, because it does not hold (measured, docs/controllers.md): a gain change of
    # 10-30 % on the other wheels often raises no alarm, and their latches stay on the healthy value.
    assert np.median(result.dwell_max_error_deg) <= V2.gates.settled_deg


# ---------------------------------------------------------------------------------------------
# Training


@pytest.mark.slow
@pytest.mark.parametrize("name", ["rma_dob", "e2e_ppo"])
def test_quick_training_is_deterministic_for_a_seed(name: str, tmp_path, monkeypatch) -> None:
    pytest.importorskip("torch")
    if name == "e2e_ppo":
        pytest.importorskip("gymnasium")
    import dataclasses
    import importlib

    from scftc_cli.training import TrainRequest, get_trainer

    # a run's determinism does not depend on its length: fewer iterations, one episode per class in
    # each checkpoint evaluation, the same code
    fewer = {"eval_faults": 1, "eval_seeds": 1}
    module, shorter = {
        "rma_dob": ("scftc_cli.versions.v2.training.rma", {"iterations": 4, "eval_every": 2, **fewer}),
        "e2e_ppo": ("scftc_cli.versions.v2.training.ppo", {"rollouts": 2, "eval_every": 1, **fewer}),
    }[name]
    budgets = importlib.import_module(module).BUDGETS
    monkeypatch.setitem(budgets, "quick", dataclasses.replace(budgets["quick"], **shorter))
    paths = []
    for run in ("a", "b"):
        out = tmp_path / run / f"{name}.npz"
        request = TrainRequest(controller=name, benchmark=V, seed=1, budget="quick", out=out)
        report = get_trainer(name, V)(request)
        assert report.artifact == out and out.with_suffix(".yaml").exists()
        paths.append(out)
    assert paths[0].read_bytes() == paths[1].read_bytes()  # the same weights, the same bytes
    arrays, _ = recurrent.load_weights(paths[0])
    assert all(np.all(np.isfinite(a)) for a in arrays.values())


def test_public_context_is_what_the_students_fly_on() -> None:
    net, config = load_student("rma_student")
    controller = StudentController(net=net, config=config)
    controller.reset(3, public_context(3))
    assert controller.estimator.shape == (3, 4)
