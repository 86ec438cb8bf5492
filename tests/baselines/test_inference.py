"""The learned controllers' numba inference (``baselines/recurrent.py``) against the torch modules
they were trained as, on feature sequences recorded from real closed-loop rollouts; and evaluation
without torch."""

from __future__ import annotations

import hashlib
import math
import re
import subprocess
import sys
import textwrap
import zipfile
from typing import Any

import numba
import numpy as np
import pytest

from scftc_cli.baselines import recurrent
from scftc_cli.baselines.policy import PolicyConfig, PolicyNet
from scftc_cli.baselines.student import StudentNet
from scftc_cli.errors import ScftcError
from scftc_cli.protocol import Context
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v1 import VERSION
from scftc_cli.versions.v1.controllers.ppo import E2EPPO, OBS_SCALE
from scftc_cli.versions.v1.controllers.rma import (
    LAYOUT,
    N_FEATURES,
    Latch,
    StudentConfig,
    StudentController,
    load_student,
)
from scftc_cli.versions.v1.sim.faults import RigidEpisodes
from scftc_cli.versions.v1.sim.testbed import TESTBED

# Agreement asked of numba vs torch (float64 both), relative over each whole sequence:
# max_t |numba - torch| <= RTOL max_t |torch| per sequence (episode axis, or episode for the
# policy). Observed ~1e-14: the two round differently (torch's BLAS order and SLEEF functions), and
# a value that crosses zero has no meaningful relative error of its own.
RTOL = 1e-12
# Cells flown to record inputs: train and held-out splits; every class a student was trained on,
# and the held-out ones it was not (gain_bias for rma_student, loss for all), a sensor fault.
CELLS = (
    ("train", "sign", None),
    ("train", "gain", None),
    ("train", "gain_bias", None),
    ("test", "sign", None),
    ("test", "gain", None),
    ("test", "gain_bias", None),
    ("test", "loss", None),
    ("test", "sign", "dropout"),
)


def cell_batches(n_faults: int = 3, n_seeds: int = 2) -> list[RigidEpisodes]:
    return [TESTBED.draw(split, c, sensor, n_faults, n_seeds) for split, c, sensor in CELLS]


def relative_error(got: np.ndarray, ref: np.ndarray, axis: int | tuple[int, ...]) -> float:
    """The largest over sequences of ``max |got - ref| / max |ref|`` along ``axis`` (time etc.)."""
    return float(np.max(np.max(np.abs(got - ref), axis=axis) / np.max(np.abs(ref), axis=axis)))


# ---------------------------------------------------------------------------------------------
# Elementary functions and the summation order


def ulps(got: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.abs((got.astype(np.longdouble) - ref) / np.spacing(np.abs(ref.astype(np.float64))))


@pytest.mark.skipif(np.finfo(np.longdouble).nmant < 60, reason="needs an extended-precision reference")
def test_exp_and_tanh_are_accurate_to_a_few_ulp() -> None:
    rng = np.random.default_rng(0)
    for lo, hi in ((-700.0, 700.0), (-3.0, 3.0), (-1e-6, 1e-6)):
        x = rng.uniform(lo, hi, 200_000)
        assert ulps(recurrent.exp_array(x), np.exp(x.astype(np.longdouble))).max() < 1.5
    for lo, hi in ((-25.0, 25.0), (-1.0, 1.0), (-0.2, 0.2), (-1e-6, 1e-6)):
        x = rng.uniform(lo, hi, 200_000)
        assert ulps(recurrent.tanh_array(x), np.tanh(x.astype(np.longdouble))).max() < 3.5


def test_exp_and_tanh_special_values() -> None:
    x = np.array([0.0, -0.0, 1e-300, -1e-300, 20.0, 30.0, -30.0, np.inf, -np.inf, np.nan])
    t = recurrent.tanh_array(x)
    assert np.array_equal(t[:4], x[:4]) and np.array_equal(np.signbit(t[:4]), np.signbit(x[:4]))
    assert np.array_equal(t[4:9], [1.0, 1.0, -1.0, 1.0, -1.0]) and np.isnan(t[9])
    e = recurrent.exp_array(np.array([0.0, 1.0, -1.0, 709.0, 800.0, -800.0, np.nan]))
    assert e[0] == 1.0 and abs(e[1] - np.e) <= np.spacing(np.e) and abs(e[2] * np.e - 1.0) < 1e-15
    assert 0.0 < e[5] < 1e-300 and np.isfinite(e[3]) and e[4] == e[3] and np.isnan(e[6])  # clamped


@pytest.mark.parametrize("n_in", [1, 3, 4, 9, 12, 32, 64])
@pytest.mark.parametrize("n_rows", [1, 3, 4, 7, 9])
def test_affine_sums_each_output_in_the_documented_order(n_in: int, n_rows: int) -> None:
    rng = np.random.default_rng(n_in * 100 + n_rows)
    w, b, v = rng.normal(size=(n_in, 5)), rng.normal(size=5), rng.normal(size=(n_rows, n_in))
    expected = np.zeros((n_rows, 5))
    for j in range(n_in):  # ((0 + w_0 v_0) + w_1 v_1) + ..., then the bias: exactly, bit for bit
        expected = expected + w[j] * v[:, j : j + 1]
    assert np.array_equal(recurrent.affine_rows(w, b, v), expected + b)


@pytest.mark.slow
def test_kernels_contain_no_fused_multiply_add() -> None:
    # No fast-math: LLVM must not contract a * b + c into an FMA (one rounding instead of two),
    # which CPUs without FMA could not reproduce. Compiled afresh: cached code cannot be inspected.
    net, _ = load_student("rma_dob")
    state = net.start(2)
    net.step(np.zeros((2, N_FEATURES)), state)
    policy = E2EPPO().net
    policy.step(np.zeros((2, 9)), policy.start(2))
    for kernel in (recurrent.student_step, recurrent.policy_step):
        fresh = numba.njit(error_model="numpy")(kernel.py_func)
        signature = kernel.signatures[0]
        fresh.compile(signature)
        asm = fresh.inspect_asm(signature)
        assert re.search(r"\bv?(mul|add|sub)[sp]d\b", asm)  # the arithmetic is there ...
        assert not re.search(r"\bvf(n)?m(add|sub)", asm)  # ... and none of it fused


def golden_inputs(shape: tuple[int, ...], salt: float) -> np.ndarray:
    """Deterministic values in [-0.5, 0.5) from exact arithmetic (no RNG stream to depend on)."""
    return (
        np.arange(np.prod(shape), dtype=np.float64).reshape(shape) * 0.6180339887498949 + salt
    ) % 1.0 - 0.5


def test_kernel_bits_are_pinned() -> None:
    # Same inputs, same bits, on every machine: the digests below were computed once; a machine,
    # numba or LLVM that rounds any operation differently fails here.
    hidden = 32
    student = StudentNet.from_state(
        {
            "scale": np.ones(N_FEATURES, dtype=np.float32),
            "inp.weight": golden_inputs((hidden, N_FEATURES), 0.1),
            "inp.bias": golden_inputs((hidden,), 0.2),
            "gru.weight_ih_l0": golden_inputs((3 * hidden, hidden), 0.3),
            "gru.weight_hh_l0": golden_inputs((3 * hidden, hidden), 0.4),
            "gru.bias_ih_l0": golden_inputs((3 * hidden,), 0.5),
            "gru.bias_hh_l0": golden_inputs((3 * hidden,), 0.6),
            "head.0.weight": golden_inputs((hidden, hidden), 0.7),
            "head.0.bias": golden_inputs((hidden,), 0.8),
            "head.2.weight": golden_inputs((3, hidden), 0.9),
            "head.2.bias": golden_inputs((3,), 0.05),
        },
        LAYOUT,
        bias_invariant=False,
    )
    x = 4.0 * golden_inputs((7, 60, N_FEATURES), 0.33)
    x[..., 10:] = 1.0
    theta = student.run(x)
    policy = PolicyNet.from_state(
        {
            "lstm.weight_ih_l0": golden_inputs((256, 9), 0.15),
            "lstm.weight_hh_l0": golden_inputs((256, 64), 0.25),
            "lstm.bias_ih_l0": golden_inputs((256,), 0.35),
            "lstm.bias_hh_l0": golden_inputs((256,), 0.45),
            "mlp.0.weight": golden_inputs((64, 64), 0.55),
            "mlp.0.bias": golden_inputs((64,), 0.65),
            "action.weight": golden_inputs((3, 64), 0.75),
            "action.bias": golden_inputs((3,), 0.85),
        },
        PolicyConfig(),
    )
    state = policy.start(5)
    u = 4.0 * golden_inputs((60, 5, 9), 0.66)
    actions = np.stack([policy.step(u[k], state) for k in range(60)])
    assert np.all(np.isfinite(theta)) and np.all(np.isfinite(actions))
    digest = {
        name: hashlib.sha256(a.tobytes()).hexdigest()[:16]
        for name, a in (("theta", theta), ("actions", actions))
    }
    assert digest == {"theta": "c959aef015547088", "actions": "64337536ce8099d2"}


# ---------------------------------------------------------------------------------------------
# Numba against torch on recorded rollouts


class _RecordingStudent(StudentController):
    """The deployed student controller, recording every step's features and estimate."""

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        self.features: list[np.ndarray] = []
        self.estimates: list[np.ndarray] = []
        self.latched: list[np.ndarray] = []

    def theta_hat(self, obs: np.ndarray) -> np.ndarray:
        theta = super().theta_hat(obs)
        self.features.append(self.estimator.features.copy())
        self.estimates.append(theta.copy())
        self.latched.append(self.estimator.latched.copy())
        return theta


def torch_student(name: str) -> Any:
    """The committed student as the torch module it was trained as, in float64."""
    torch = pytest.importorskip("torch")  # the reference only: evaluation never imports it
    from scftc_cli.training.student import StudentModule
    from scftc_cli.versions.v1.controllers.rma import LAYOUT

    arrays, doc = recurrent.load_weights(VERSION.weights_dir / f"{name}.npz")
    config = StudentConfig.from_dict(doc)
    model = StudentModule(LAYOUT, config.hidden, config.bias_invariant)
    model.load_state_dict({k: torch.from_numpy(v) for k, v in arrays.items()})
    return model.double().eval()


@pytest.mark.parametrize("name", ["rma_student", "rma_dob"])
def test_student_matches_torch_on_recorded_rollouts(name: str) -> None:
    torch = pytest.importorskip("torch")
    net, config = load_student(name)
    model = torch_student(name)
    assert config.bias_invariant == (name == "rma_dob")
    worst = 0.0
    for episodes in cell_batches():
        controller = _RecordingStudent(net=net, config=config)
        rollout(controller, episodes)
        n, steps = episodes.n, len(controller.features)
        x = np.stack(controller.features, axis=1)  # (3n, T, F): whole episodes
        assert x.shape == (3 * n, steps, N_FEATURES) and steps == 400
        with torch.no_grad():
            reference = model(torch.from_numpy(x))[0].numpy()  # (3n, T), one call per sequence
        mine = net.run(x)  # every step, also after latching
        worst = max(worst, relative_error(mine, reference, axis=1))
        assert relative_error(mine, reference, axis=1) < RTOL

        # The latch on torch's estimates latches the same axes at the same steps as the deployed
        # controller did, and the controller (which stops evaluating latched axes) reports the
        # very numbers of the full sequence run through the latch.
        excitation = np.cumsum(x[:, :, 2] ** 2, axis=1)  # sum of da^2, in the estimator's order
        latch_torch, latch_mine = Latch(config.latch, n), Latch(config.latch, n)
        from_torch, from_mine = [], []
        for k in range(steps):
            e = excitation[:, k].reshape(n, 3)
            from_torch.append(latch_torch.update(reference[:, k].reshape(n, 3), e))
            from_mine.append(latch_mine.update(mine[:, k].reshape(n, 3), e))
            assert np.array_equal(latch_torch.latched, controller.latched[k])
            assert np.array_equal(from_mine[k], controller.estimates[k])
        assert relative_error(np.stack(from_mine), np.stack(from_torch), axis=0) < RTOL
        if episodes.split == "train":
            assert controller.latched[-1].mean() > 0.5  # the latch is exercised
    assert worst > 0.0  # torch's own kernels round differently: the comparison is not vacuous


def test_policy_matches_torch_on_recorded_rollouts() -> None:
    torch = pytest.importorskip("torch")
    from scftc_cli.training.policy import RecurrentPolicy

    arrays, doc = recurrent.load_weights(VERSION.weights_dir / "e2e_ppo.npz")
    model = RecurrentPolicy(PolicyConfig.from_dict(doc), len(OBS_SCALE), 3)
    model.load_state_dict({k: torch.from_numpy(v) for k, v in arrays.items()})
    model = model.double().eval()
    net = E2EPPO().net

    class Recording(E2EPPO):
        def act(self, obs: np.ndarray) -> np.ndarray:
            self.inputs.append(self.policy_input(obs, self.prev_action))
            command = super().act(obs)
            self.commands.append(command)
            return command

    for episodes in cell_batches():
        controller = Recording(net=net)
        controller.inputs, controller.commands = [], []
        rollout(controller, episodes)
        u = np.stack(controller.inputs)  # (T, n, 9)
        with torch.no_grad():
            reference = model(torch.from_numpy(u))[0].numpy()  # (T, n, 3)
        state = net.start(episodes.n)
        mine = np.stack([net.step(u[k], state) for k in range(len(u))])
        assert relative_error(mine, reference, axis=(0, 2)) < RTOL
        assert np.array_equal(np.clip(mine, -1.0, 1.0), np.stack(controller.commands))


# ---------------------------------------------------------------------------------------------
# No torch on the evaluation path


def test_weights_load_and_learned_controllers_evaluate_without_torch() -> None:
    script = textwrap.dedent(
        """
        import sys
        sys.modules["torch"] = None  # any `import torch` now raises ImportError
        from scftc_cli.versions.v1.controllers.ppo import E2EPPO
        from scftc_cli.versions.v1.controllers.rma import load_student
        from scftc_cli.evaluate import Cell, evaluate_cell
        from scftc_cli.registry import make_controller
        from scftc_cli.versions.v1.spec import V1

        E2EPPO()
        for name in ("rma_student", "rma_dob"):
            load_student(name)
        for name in ("rma_dob", "rma_student", "e2e_ppo"):
            cell = Cell("test", "gain_bias")
            run = evaluate_cell(lambda _c: make_controller(name), V1, cell, n_faults=2, n_seeds=1)
            assert run.result.n == 2
        assert sys.modules["torch"] is None
        print("ok")
        """
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr


def test_weights_files_are_plain_npz(tmp_path) -> None:
    arrays = {"a.weight": np.arange(6, dtype=np.float32).reshape(2, 3), "a.bias": np.ones(2, np.float32)}
    first = recurrent.save_weights(tmp_path / "one.npz", arrays, {"hidden": 2})
    second = recurrent.save_weights(tmp_path / "two.npz", arrays, {"hidden": 2})
    assert first.read_bytes() == second.read_bytes()  # no timestamps: same weights, same bytes
    loaded, config = recurrent.load_weights(first)
    assert config == {"hidden": 2} and list(loaded) == list(arrays)
    assert all(loaded[k].dtype == np.float32 and np.array_equal(loaded[k], arrays[k]) for k in arrays)
    with np.load(first, allow_pickle=False) as blob:  # a plain numpy archive
        assert set(blob.files) == {"a.weight", "a.bias", "config"}
    with pytest.raises(ValueError, match="reserved"):
        recurrent.save_weights(tmp_path / "x.npz", {"config": np.ones(1, np.float32)}, {})
    with pytest.raises(ValueError, match="float32"):
        recurrent.save_weights(tmp_path / "x.npz", {"w": np.ones(1)}, {})  # float64: no silent rounding
    old = tmp_path / "old.pt"  # a torch state dict is a zip archive of pickles
    with zipfile.ZipFile(old, "w") as archive:
        archive.writestr("old/data.pkl", b"\x80\x02}q\x00.")
    text = tmp_path / "text.npz"
    text.write_text("not weights")
    for wrong in (old, text):
        with pytest.raises(ScftcError, match="not a weights file"):
            recurrent.load_weights(wrong)


def test_prior_clamp_constants_are_the_correctly_rounded_logs() -> None:
    from scftc_cli.versions.v1.controllers.rma import LOG_MAG_MAX, LOG_MAG_MIN

    assert LOG_MAG_MIN == float(np.log(np.longdouble(0.1))) == math.log(0.1)
    assert LOG_MAG_MAX == float(np.log(np.longdouble(3.0))) == math.log(3.0)
