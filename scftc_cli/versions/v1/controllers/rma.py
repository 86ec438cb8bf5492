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
(``controllers/observer.py``), so axis ``i`` is estimated from its own history of ``(a_i, dW_i,
sigma_i, w_i)``. Sharing the weights across axes makes the estimator blind to how many axes are
reversed, which is exactly what the held-out sign patterns change.

The persistence-of-excitation latch freezes each axis' estimate once the commands varied enough
and the estimate stopped moving; in the settled phase there is no excitation left, and a live
estimate could wander and make the loop limit-cycle. ``rma_dob`` adds the disturbance observer
of docs/benchmark.md on top of a student trained with train-split biases in the loop; that student
sees only bias-invariant features (first differences: ``ddW = theta da`` under a constant bias),
so a bias outside the train range cannot fake the authority it reports.

The student's output layer is a least-squares fit whose weights and prior the GRU chooses
(``baselines/student.py``): a plain regression head cannot answer outside the authorities it was trained
on, and the held-out split's go below the train range by construction. Measured: the first,
direct-regression student estimated held-out axes of ``|theta|`` 0.13-0.25 at ~0.27-0.36
(``rma_dob`` 86.0 % settled on ``gain_bias``); the fit identifies them to a median 0.1 % (93.6 %).

The network (``training/student.py``'s module, trained in ``training/rma.py``) is the one every
version's students share (``baselines/student.py``); this version's ``LAYOUT`` says what it reads.
Evaluation runs it with the numba kernel and never imports torch. Weights live in this version's
``weights/<name>.npz`` with a sidecar ``<name>.yaml`` (provenance);
``scftc train --controller rma_student|rma_dob`` regenerates them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scftc_cli.baselines import student
from scftc_cli.baselines.params import committed_weights
from scftc_cli.baselines.student import StudentLayout, StudentNet, StudentNetLike
from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v1.controllers.analytic import analytic_command, nominal_command
from scftc_cli.versions.v1.controllers.observer import DisturbanceObserver, TorqueMeter
from scftc_cli.versions.v1.spec import V1

N_FEATURES = 12
RATIO_EPS = 0.01  # regularizes the one-step ratio where the command was small
RATIO_DIFF_EPS = 1e-4  # ... and the first-difference ratio where the command barely changed
RATIO_CLIP = 4.0
# log 0.1 and log 3 (train |theta| in [0.25, 1.875]), correctly rounded: written out, because a
# library's log may round differently on another CPU and move the clamp of every prior.
LOG_MAG_MIN, LOG_MAG_MAX = -2.3025850929940455, 1.0986122886681098
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


LAYOUT = StudentLayout(
    feature_scale=FEATURE_SCALE,
    biased_features=BIASED_FEATURES,
    raw_pair=RAW_PAIR,
    diff_pair=DIFF_PAIR,
    prior_weight=PRIOR_WEIGHT,
    log_mag_min=LOG_MAG_MIN,
    log_mag_max=LOG_MAG_MAX,
)
"""What the per-axis student reads (``baselines/student.py`` runs it)."""


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


class Latch:
    """The per-axis persistence-of-excitation latch (``LatchConfig``) of a batch ``(n, 3)``.

    Per step: ``theta = latch.update(raw, excitation)`` with the live estimate ``raw`` and the
    summed squared command changes ``excitation``; axes that latch keep the estimate of the step
    they latched at from then on (``latched``, ``frozen``).
    """

    def __init__(self, config: LatchConfig, n: int) -> None:
        self.config = config
        self.k = 0
        self.history = np.zeros((config.window + 1, n, 3))  # ring buffer of raw estimates
        self.latched = np.zeros((n, 3), dtype=bool)
        self.frozen = np.zeros((n, 3))

    def update(self, raw: np.ndarray, excitation: np.ndarray) -> np.ndarray:
        """Fold in step ``k``'s ``raw`` ``(n, 3)``; returns the estimate to use, latched where frozen."""
        cfg, k = self.config, self.k
        self.k += 1
        self.history[k % (cfg.window + 1)] = raw
        if k >= max(cfg.min_steps, cfg.window):
            spread = self.history.max(axis=0) - self.history.min(axis=0)
            still = spread <= cfg.tolerance * np.maximum(np.abs(raw), 0.1)
            due = still | (k >= cfg.max_steps)
            now = ~self.latched & due & (excitation >= cfg.min_excitation)
            self.frozen = np.where(now, raw, self.frozen)
            self.latched |= now
        return np.where(self.latched, self.frozen, raw)


class StudentEstimator:
    """Runs the student online over a batch and applies the latch.

    Per step: ``theta = est.estimate(obs)`` (``(n, 3)``, latched where frozen), then
    ``est.hold(command)`` with the command as applied. ``features`` keeps the last step's input
    (the trainer records it), ``raw`` the live estimate, ``latched`` which axes are frozen. The
    network is no longer evaluated on a frozen axis (nothing reads it), so there ``raw`` stays at
    the value it latched with.
    """

    def __init__(self, net: StudentNetLike, latch: LatchConfig, context: Context) -> None:
        self.net, self.context = net, context
        n = context.n
        self.meter = TorqueMeter(context)
        self.state = net.start(n * 3)
        self.k = 0
        self.last_command = np.zeros((n, 3))  # a_{k-1}, zero before the first step
        self.last_dw = np.zeros((n, 3))  # dW_{k-1}
        self.measured = False  # whether last_dw was measured (k >= 1)
        self.excitation = np.zeros((n, 3))
        self.latch = Latch(latch, n)
        self.raw = np.zeros((n, 3))
        self.features = np.zeros((n * 3, N_FEATURES))

    @property
    def latched(self) -> np.ndarray:
        return self.latch.latched

    @property
    def frozen(self) -> np.ndarray:
        return self.latch.frozen

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
        theta = self.net.step(self.features, self.state, ~self.latch.latched.reshape(-1))
        self.raw = theta.reshape(n, 3).copy()
        self.k += 1
        return self.latch.update(self.raw, self.excitation)

    def hold(self, command: np.ndarray) -> None:
        """Record the command ``(n, 3)`` applied over the coming step."""
        self.meter.hold(command)


def load_student(name: str, path: Path | None = None) -> tuple[StudentNet, StudentConfig]:
    """The committed student ``name`` (or the one at ``path``), ready for the kernel (float64)."""
    return student.load_student(path or committed_weights(name, V1.version), LAYOUT, StudentConfig)


class StudentController(Controller):
    """The analytic law fed the student's latched ``theta_hat`` (and, with ``observer_gain > 0``,
    the disturbance observer's ``beta_hat``)."""

    name = "rma_student"

    def __init__(
        self, path: Path | None = None, net: StudentNetLike | None = None, config: StudentConfig | None = None
    ) -> None:
        if net is None or config is None:
            net, config = load_student(self.name, path)
        self.net, self.config = net, config

    def reset(self, n: int, context: Context) -> None:
        self.context = context
        self.estimator = StudentEstimator(self.net, self.config.latch, context)
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
    """The RMA student; weights: this version's ``weights/rma_student.npz``."""

    name = "rma_student"


class RMADob(StudentController):
    """The gain student composed with the disturbance observer; weights ``rma_dob.npz``."""

    name = "rma_dob"
