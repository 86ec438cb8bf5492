"""``rma_student`` and ``rma_dob``: learn to *identify* the fault, let the analytic law control.

RMA (Kumar et al. 2021, arXiv 2107.04034) trains a privileged teacher and a student that infers
the teacher's privileged input from the history of commands and responses. Here the teacher is the
analytic law fed the true ``theta = g/f`` (``teacher``), and the student is a GRU-driven
least-squares estimator of the *identifiable* per-axis authority ``theta`` (docs/benchmark.md),
online. The source study
regressed ``[g0, g1, g2, f-1]`` instead, which is ill-posed: scaling ``g``, ``b`` and ``f``
together leaves every trajectory unchanged, so that regression can only learn a conditional mean.

The student is one small GRU shared by the three body axes: after the gyroscopic term is removed
with the nominal inertia, each axis obeys ``dW_i = theta_i a_i + beta_i`` on its own
(``baselines/observer.py``), so axis ``i`` is estimated from its own history of ``(a_i, dW_i,
sigma_i, w_i)``. Sharing the weights across axes makes the estimator blind to how many axes are
reversed, which is exactly what the held-out sign patterns change.

The persistence-of-excitation latch freezes each axis' estimate once the commands varied enough
and the estimate stopped moving; in the settled phase there is no excitation left, and a live
estimate could wander and make the loop limit-cycle. ``rma_dob`` adds the disturbance observer
of docs/benchmark.md on top of a student trained with train-split biases in the loop; that student
sees only bias-invariant features (first differences: ``ddW = theta da`` under a constant bias),
so a bias outside the train range cannot fake the authority it reports.

The student's output layer is a least-squares fit whose weights and prior the GRU chooses
(``ThetaStudent``): a plain regression head cannot answer outside the authorities it was trained
on, and the held-out split's go below the train range by construction. Measured: the first,
direct-regression student estimated held-out axes of ``|theta|`` 0.13-0.25 at ~0.27-0.36
(``rma_dob`` 86.0 % settled on ``gain_bias``); the fit identifies them to a median 0.1 % (93.6 %).

Weights live in ``scftc_cli/weights/<name>.pt`` with a sidecar ``<name>.yaml`` (provenance);
``scftc train --controller rma_student|rma_dob`` regenerates them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.nn import functional

from scftc_cli.baselines.analytic import analytic_command, nominal_command
from scftc_cli.baselines.observer import DisturbanceObserver, TorqueMeter
from scftc_cli.baselines.params import WEIGHTS_DIR
from scftc_cli.baselines.torch_runtime import inference_mode_threads
from scftc_cli.errors import ScftcError
from scftc_cli.protocol import Context, Controller

N_FEATURES = 12
RATIO_EPS = 0.01  # regularizes the one-step ratio where the command was small
RATIO_DIFF_EPS = 1e-4  # ... and the first-difference ratio where the command barely changed
RATIO_CLIP = 4.0
LOG_MAG_MIN, LOG_MAG_MAX = float(np.log(0.1)), float(np.log(3.0))  # train |theta| in [0.25, 1.875]
# Fixed input scaling (about 1 / std of each feature over early train-split steps): the
# differences are small, and unscaled they train several times slower.
FEATURE_SCALE = (5.0, 8.0, 15.0, 100.0, 13.0, 8.0, 3.0, 2.0, 8.0, 35.0, 1.0, 1.0)
# Features a constant bias shifts (dW, a dW, a dW / a^2). A bias-invariant student (rma_dob's)
# reads theta from first differences only, ddW = theta da exactly, so no bias, however far
# outside the train range, can fake the sign or size of the authority it reports.
BIASED_FEATURES = (1, 4, 6)
# Columns (x, y, valid) of the least-squares pair y = theta x: (a, dW) or, bias-invariant, (da, ddW).
RAW_PAIR, DIFF_PAIR = (0, 1, 10), (2, 3, 11)
# Strength of the GRU's prior guess in units of the summed weighted x^2; about a tenth of the
# excitation the latch asks for, so the data dominate by the time an axis can latch.
PRIOR_WEIGHT = 0.01
StudentState = tuple[torch.Tensor | None, torch.Tensor | float, torch.Tensor | float]


@dataclass(frozen=True)
class LatchConfig:
    """Per-axis persistence-of-excitation latch.

    An axis latches at step ``k >= min_steps`` once the summed squared command changes reached
    ``min_excitation`` and the raw estimate moved less than ``tolerance * max(|theta_hat|, 0.1)``
    over the last ``window`` steps, or, excitation reached, at step ``max_steps`` at the latest
    (before the vehicle comes to rest, where a bias makes the history uninformative); from then
    on its estimate is frozen.
    """

    min_steps: int = 10
    max_steps: int = 80
    min_excitation: float = 0.1
    window: int = 10
    tolerance: float = 0.02


@dataclass(frozen=True)
class StudentConfig:
    """Architecture and deployment settings stored with the weights."""

    hidden: int = 32
    latch: LatchConfig = LatchConfig()
    observer_gain: float = 0.0  # > 0: compose with the disturbance observer (rma_dob)
    bias_invariant: bool = False  # see only features that a constant bias cannot shift

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StudentConfig:
        return cls(
            hidden=int(d["hidden"]),
            latch=LatchConfig(**d["latch"]),
            observer_gain=float(d["observer_gain"]),
            bias_invariant=bool(d.get("bias_invariant", False)),
        )


class ThetaStudent(nn.Module):
    """Per-axis GRU: features ``(B, T, N_FEATURES)`` -> ``theta_hat`` ``(B, T)``, with ``B`` the
    number of (episode, axis) sequences.

    The output is a least-squares fit whose sample weights and prior the GRU chooses:

        theta_hat_t = (sum_s w_s x_s y_s + P m_t) / (sum_s w_s x_s^2 + P),  s <= t

    with ``(x, y) = (a, dW)``, or ``(da, ddW)`` for a bias-invariant student (``y = theta x``
    exactly in either case, up to the gyroscopic rounding), ``w_s >= 0`` a learned per-step
    weight (zero where the pair was not measured) and ``m_t = tanh(logit / 2) |theta|_hat`` a
    learned prior guess of fixed strength ``PRIOR_WEIGHT``. The GRU decides which samples to trust
    and what to say before the data are informative; the data, not the network's output range,
    decide the size of the answer. A plain regression head cannot answer outside the ``|theta|``
    it was trained on (the held-out split's authorities go below the train range by
    construction, docs/benchmark.md); this one is equivariant to the authority's scale once the data
    outweigh the prior.
    """

    scale: torch.Tensor  # a registered buffer

    def __init__(self, hidden: int = 32, bias_invariant: bool = False) -> None:
        super().__init__()
        scale = torch.tensor(FEATURE_SCALE)
        if bias_invariant:
            scale[list(BIASED_FEATURES)] = 0.0
        self.register_buffer("scale", scale)
        self.pair = DIFF_PAIR if bias_invariant else RAW_PAIR
        self.inp = nn.Linear(N_FEATURES, hidden)
        self.gru = nn.GRU(hidden, hidden, batch_first=True)
        self.head = nn.Sequential(nn.Linear(hidden, hidden), nn.Tanh(), nn.Linear(hidden, 3))

    def heads(
        self, x: torch.Tensor, state: StudentState | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, StudentState]:
        """``(sign_logit, log_magnitude, theta_hat, state)``, the first three ``(B, T)``: the
        prior's two heads (magnitude clamped to ``[LOG_MAG_MIN, LOG_MAG_MAX]``) and the fit."""
        h0, sxy0, sxx0 = state if state is not None else (None, 0.0, 0.0)
        y, h = self.gru(torch.tanh(self.inp(x * self.scale)), h0)
        out = self.head(y)
        logit, log_mag = out[..., 0], out[..., 1].clamp(LOG_MAG_MIN, LOG_MAG_MAX)
        prior = torch.tanh(0.5 * logit) * torch.exp(log_mag)
        col_x, col_y, col_valid = self.pair
        weight = functional.softplus(out[..., 2]) * x[..., col_valid]
        xs, ys = x[..., col_x], x[..., col_y]
        sxy = sxy0 + torch.cumsum(weight * xs * ys, dim=1)
        sxx = sxx0 + torch.cumsum(weight * xs * xs, dim=1)
        theta = (sxy + PRIOR_WEIGHT * prior) / (sxx + PRIOR_WEIGHT)
        return logit, log_mag, theta, (h, sxy[:, -1:], sxx[:, -1:])

    def forward(
        self, x: torch.Tensor, state: StudentState | None = None
    ) -> tuple[torch.Tensor, StudentState]:
        """``(theta_hat (B, T), state)``; pass ``state`` back in to continue the sequences."""
        _, _, theta, state = self.heads(x, state)
        return theta, state


def axis_features(
    obs: np.ndarray,
    a_prev: np.ndarray,
    dw_prev: np.ndarray,
    da: np.ndarray,
    ddw: np.ndarray,
    valid1: float,
    valid2: float,
) -> np.ndarray:
    """``(n * 3, N_FEATURES)`` features, episode-major then axis, for ``obs`` ``(n, 6)`` and the
    last step's command ``a_prev``, measured torque ``dw_prev`` and their first differences
    ``da``, ``ddw`` (all ``(n, 3)``). ``valid1``/``valid2`` flag that one/two steps were measured.

    The products ``a dW`` and ``a^2`` are the sufficient statistics of a least-squares fit of
    ``dW = theta a + beta``, and the regularized ratios ``a dW / (a^2 + eps)`` (exact ``theta``
    without bias) and ``da ddW / (da^2 + eps)`` (exact ``theta`` under a constant bias) the
    one-step estimates; handing them over saves the GRU from learning to multiply and divide.
    """
    n = obs.shape[0]
    ratio = np.clip(a_prev * dw_prev / (a_prev * a_prev + RATIO_EPS), -RATIO_CLIP, RATIO_CLIP)
    ratio_diff = np.clip(da * ddw / (da * da + RATIO_DIFF_EPS), -RATIO_CLIP, RATIO_CLIP)
    cols = (
        a_prev,
        dw_prev,
        da,
        ddw,
        a_prev * dw_prev,
        a_prev * a_prev,
        ratio,
        ratio_diff,
        obs[:, :3],
        obs[:, 3:],
        np.full((n, 3), valid1),
        np.full((n, 3), valid2),
    )
    return np.stack(cols, axis=-1).reshape(n * 3, N_FEATURES)


class StudentEstimator:
    """Runs the student online over a batch and applies the latch.

    Per step: ``theta = est.estimate(obs)`` (``(n, 3)``, latched where frozen), then
    ``est.hold(command)`` with the command as applied. ``features`` keeps the last step's input
    (the trainer records it), ``raw`` the live GRU estimate, ``latched`` which axes are frozen.
    """

    def __init__(self, model: ThetaStudent, latch: LatchConfig, context: Context) -> None:
        self.model, self.latch, self.context = model, latch, context
        self.dtype = next(model.parameters()).dtype
        n = context.n
        self.meter = TorqueMeter(context)
        self.state: StudentState | None = None
        self.k = 0
        self.last_command = np.zeros((n, 3))  # a_{k-1}, zero before the first step
        self.last_dw = np.zeros((n, 3))  # dW_{k-1}
        self.measured = False  # whether last_dw was measured (k >= 1)
        self.excitation = np.zeros((n, 3))
        self.history = np.zeros((latch.window + 1, n, 3))  # ring buffer of raw estimates
        self.latched = np.zeros((n, 3), dtype=bool)
        self.frozen = np.zeros((n, 3))
        self.raw = np.zeros((n, 3))
        self.features = np.zeros((n * 3, N_FEATURES))

    @torch.no_grad()
    def estimate(self, obs: np.ndarray) -> np.ndarray:
        """``theta_hat`` ``(n, 3)`` after observing ``obs`` ``(n, 6)``."""
        n = obs.shape[0]
        dw, a_prev = self.meter.read(obs)
        if dw is None or a_prev is None:
            dw, a_prev, valid1 = np.zeros((n, 3)), np.zeros((n, 3)), 0.0
        else:
            valid1 = 1.0
        valid2 = 1.0 if self.k >= 2 else 0.0
        da, ddw = a_prev - self.last_command, (dw - self.last_dw) * valid2
        self.excitation += da * da
        self.features = axis_features(obs, a_prev, dw, da, ddw, valid1, valid2)
        self.last_command, self.last_dw, self.measured = a_prev, dw, valid1 > 0.0
        x = torch.from_numpy(self.features).to(self.dtype)[:, None, :]
        theta, self.state = self.model(x, self.state)
        self.raw = theta[:, 0].double().numpy().reshape(n, 3)
        self._latch()
        self.k += 1
        return np.where(self.latched, self.frozen, self.raw)

    def _latch(self) -> None:
        cfg = self.latch
        slot = self.k % (cfg.window + 1)
        self.history[slot] = self.raw
        if self.k < max(cfg.min_steps, cfg.window):
            return
        spread = self.history.max(axis=0) - self.history.min(axis=0)
        still = spread <= cfg.tolerance * np.maximum(np.abs(self.raw), 0.1)
        due = still | (self.k >= cfg.max_steps)
        now = ~self.latched & due & (self.excitation >= cfg.min_excitation)
        self.frozen = np.where(now, self.raw, self.frozen)
        self.latched |= now

    def hold(self, command: np.ndarray) -> None:
        """Record the command ``(n, 3)`` applied over the coming step."""
        self.meter.hold(command)


def weights_path(name: str) -> Path:
    return WEIGHTS_DIR / f"{name}.pt"


def save_student(model: ThetaStudent, config: StudentConfig, path: Path) -> Path:
    """Write the weights (float32 state dict + config) to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().float().clone() for k, v in model.state_dict().items()}
    torch.save({"config": config.to_dict(), "state_dict": state}, path)
    return path


def load_student(name: str, path: Path | None = None) -> tuple[ThetaStudent, StudentConfig]:
    """The committed student ``name`` (in float64 for reproducible inference)."""
    path = path or weights_path(name)
    if not path.exists():
        raise ScftcError(f"no weights at {path}; run `scftc train --controller {name}`")
    inference_mode_threads()
    blob = torch.load(path, map_location="cpu", weights_only=True)
    config = StudentConfig.from_dict(blob["config"])
    model = ThetaStudent(config.hidden, config.bias_invariant)
    model.load_state_dict(blob["state_dict"])
    return model.double().eval(), config


class StudentController(Controller):
    """The analytic law fed the student's latched ``theta_hat`` (and, with ``observer_gain > 0``,
    the disturbance observer's ``beta_hat``)."""

    name = "rma_student"

    def __init__(
        self,
        path: Path | None = None,
        model: ThetaStudent | None = None,
        config: StudentConfig | None = None,
    ) -> None:
        if model is None or config is None:
            model, config = load_student(self.name, path)
        self.model, self.config = model, config

    def reset(self, n: int, context: Context) -> None:
        self.context = context
        self.estimator = StudentEstimator(self.model, self.config.latch, context)
        self.observer = DisturbanceObserver(n, self.config.observer_gain)
        self.beta_hat = np.zeros((n, 3))

    def theta_hat(self, obs: np.ndarray) -> np.ndarray:
        """The ``(n, 3)`` authority the law divides by (the trainer mixes in the teacher's)."""
        return self.estimator.estimate(obs)

    def act(self, obs: np.ndarray) -> np.ndarray:
        theta_hat = self.theta_hat(obs)
        est = self.estimator
        if self.config.observer_gain > 0.0 and est.measured:
            self.beta_hat = self.observer.update(est.last_dw, est.last_command, theta_hat)
        command = analytic_command(nominal_command(obs, self.context), theta_hat, self.beta_hat)
        est.hold(command)
        return command


class RMAStudent(StudentController):
    """The RMA student; weights ``scftc_cli/weights/rma_student.pt``."""

    name = "rma_student"


class RMADob(StudentController):
    """The gain student composed with the disturbance observer; weights ``rma_dob.pt``."""

    name = "rma_dob"
