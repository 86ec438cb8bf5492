"""The RMA student network, deployed: one per-actuator GRU whose output layer is a least-squares
fit, run by the numba kernel ``recurrent.student_step`` (no torch at evaluation).

Every version's RMA controllers (``rma_student``, ``rma_dob``) use this network; what differs is
what it reads (``StudentLayout``: the version's per-actuator features, their scaling, the columns
of the fit's pair and the strength of its prior), and what the estimate means (``theta = g/f`` of
a body axis on v1, a wheel's effectiveness ``g`` on v2). The fit,

    estimate_t = (sum_s w_s x_s y_s + P m_t) / (sum_s w_s x_s^2 + P),  s from the last restart to t,

has sample weights ``w_s = softplus(.) valid_s`` and a prior guess ``m_t = tanh(logit / 2)
e^clamp(log_mag)`` that the GRU chooses, of fixed strength ``P``: a plain regression head cannot
answer outside the magnitudes it was trained on, this one is equivariant to the magnitude once the
data outweigh the prior. Weights are the float32 arrays as trained (``training/student.py``),
held as float64 copies (exact), matrices transposed to ``(in, out)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, TypeVar

import numpy as np

from scftc_cli.baselines import recurrent
from scftc_cli.errors import ScftcError
from scftc_cli.sim.rows import HEAVY_PARALLEL_MIN_BATCH, run_rows


@dataclass(frozen=True)
class StudentLayout:
    """What a version's student reads, and how its fit is set up.

    Attributes:
        feature_scale: fixed input scaling, one per feature (about 1 / its spread on train steps).
        biased_features: the features a constant offset shifts; a bias-invariant student never
            reads them (scaled by zero).
        raw_pair, diff_pair: the ``(x, y, valid)`` columns of the fit's pair ``y = estimate x``:
            raw (command and measured torque) or first differences (bias-invariant).
        prior_weight: the prior's strength ``P``, in units of the summed weighted ``x^2``.
        log_mag_min, log_mag_max: the clamp of the prior's log-magnitude.
    """

    feature_scale: tuple[float, ...]
    biased_features: tuple[int, ...]
    raw_pair: tuple[int, int, int]
    diff_pair: tuple[int, int, int]
    prior_weight: float
    log_mag_min: float
    log_mag_max: float

    @property
    def n_features(self) -> int:
        return len(self.feature_scale)

    def scale(self, bias_invariant: bool) -> np.ndarray:
        """The fixed input scaling ``(n_features,)`` float32, zero on ``biased_features`` for a
        bias-invariant student."""
        scale = np.array(self.feature_scale, dtype=np.float32)
        if bias_invariant:
            scale[list(self.biased_features)] = 0.0
        return scale

    def pair(self, bias_invariant: bool) -> tuple[int, int, int]:
        """The fit's ``(x, y, valid)`` columns."""
        return self.diff_pair if bias_invariant else self.raw_pair


@dataclass(frozen=True, eq=False)
class StudentState:
    """The recurrent state of ``B`` sequences: GRU ``h`` ``(B, H)``, the fit's running sums
    ``(sum w x y, sum w x^2)`` ``(B, 2)`` and the last estimate ``(B,)``; updated in place."""

    h: np.ndarray
    sums: np.ndarray
    estimate: np.ndarray


@dataclass(frozen=True, eq=False)
class StudentNet:
    """A trained student's weights, laid out for the numba kernel (module docstring)."""

    scale: np.ndarray
    w_in: np.ndarray
    b_in: np.ndarray
    w_ih: np.ndarray
    b_ih: np.ndarray
    w_hh: np.ndarray
    b_hh: np.ndarray
    w_1: np.ndarray
    b_1: np.ndarray
    w_2: np.ndarray
    b_2: np.ndarray
    pair: tuple[int, int, int]
    prior_weight: float
    log_mag_min: float
    log_mag_max: float

    @classmethod
    def from_state(
        cls, state: Mapping[str, np.ndarray], layout: StudentLayout, bias_invariant: bool
    ) -> StudentNet:
        """From a trained module's state dict as numpy arrays (the keys of the ``.npz`` file)."""
        t, f = recurrent.transposed, recurrent.as_float64
        return cls(
            scale=f(state["scale"]),
            w_in=t(state["inp.weight"]),
            b_in=f(state["inp.bias"]),
            w_ih=t(state["gru.weight_ih_l0"]),
            b_ih=f(state["gru.bias_ih_l0"]),
            w_hh=t(state["gru.weight_hh_l0"]),
            b_hh=f(state["gru.bias_hh_l0"]),
            w_1=t(state["head.0.weight"]),
            b_1=f(state["head.0.bias"]),
            w_2=t(state["head.2.weight"]),
            b_2=f(state["head.2.bias"]),
            pair=layout.pair(bias_invariant),
            prior_weight=layout.prior_weight,
            log_mag_min=layout.log_mag_min,
            log_mag_max=layout.log_mag_max,
        )

    @property
    def hidden(self) -> int:
        return self.w_hh.shape[0]

    def start(self, rows: int) -> StudentState:
        """The state of ``rows`` fresh sequences."""
        return StudentState(np.zeros((rows, self.hidden)), np.zeros((rows, 2)), np.zeros(rows))

    def step(
        self,
        x: np.ndarray,
        state: StudentState,
        active: np.ndarray | None = None,
        restart: np.ndarray | None = None,
    ) -> np.ndarray:
        """Advance ``state`` by one step's features ``x`` ``(B, n_features)`` on the rows where
        ``active`` ``(B,)`` is set (all by default; the others keep their state and estimate),
        first restarting the rows of ``restart`` (hidden state and fit zeroed); returns the
        estimate ``(B,)`` (``state.estimate``, updated in place)."""
        if active is None:
            active = np.ones(x.shape[0], dtype=np.bool_)
        if restart is not None and restart.any():
            state.h[restart] = 0.0
            state.sums[restart] = 0.0
        run_rows(
            recurrent.student_step,
            np.ascontiguousarray(x, dtype=np.float64),
            np.ascontiguousarray(active, dtype=np.bool_),
            self.scale,
            state.h,
            state.sums,
            state.estimate,
            self.w_in,
            self.b_in,
            self.w_ih,
            self.b_ih,
            self.w_hh,
            self.b_hh,
            self.w_1,
            self.b_1,
            self.w_2,
            self.b_2,
            *self.pair,
            self.prior_weight,
            self.log_mag_min,
            self.log_mag_max,
            parallel=x.shape[0] >= HEAVY_PARALLEL_MIN_BATCH,
        )
        return state.estimate

    def run(self, x: np.ndarray, restart: np.ndarray | None = None) -> np.ndarray:
        """The estimate ``(B, T)`` of whole feature sequences ``x`` ``(B, T, n_features)``, every
        step active, with the restarts ``restart`` ``(B, T)`` (before the step) if given."""
        state = self.start(x.shape[0])
        out = []
        for k in range(x.shape[1]):
            self.step(x[:, k], state, restart=None if restart is None else restart[:, k])
            out.append(state.estimate.copy())
        return np.stack(out, axis=1)


class StudentNetLike(Protocol):
    """What an estimator needs of a student network: ``StudentNet`` (the numba kernel, deployed)
    or a trainer's torch module stepped in float64."""

    def start(self, rows: int) -> Any:
        """The state of ``rows`` fresh sequences."""

    def step(self, x: np.ndarray, state: Any, active: np.ndarray | None = None) -> np.ndarray:
        """The estimate ``(B,)`` after the features ``x`` ``(B, n_features)`` of one step."""


class StudentConfigLike(Protocol):
    """What the weights file's config says about the network (each version's ``StudentConfig``)."""

    @property
    def hidden(self) -> int: ...

    @property
    def bias_invariant(self) -> bool: ...

    def to_dict(self) -> dict[str, Any]: ...


ConfigT = TypeVar("ConfigT", bound=StudentConfigLike)


def save_student(state: Mapping[str, np.ndarray], config: StudentConfigLike, path: Path) -> Path:
    """Write a trained student's state dict (numpy, stored as float32) and ``config`` to the
    ``.npz`` file ``path``."""
    return recurrent.save_weights(path, dict(state), config.to_dict())


def load_student(path: Path, layout: StudentLayout, config_type: type[ConfigT]) -> tuple[StudentNet, ConfigT]:
    """The student of the weights file ``path``, ready for the kernel (float64), and its config
    (``config_type.from_dict`` of the file's).

    Raises:
        ScftcError: the weights do not have the shape the config and the layout describe.
    """
    state, doc = recurrent.load_weights(path)
    config = config_type.from_dict(doc)  # type: ignore[attr-defined]
    net = StudentNet.from_state(state, layout, config.bias_invariant)
    if net.hidden != config.hidden or net.scale.shape != (layout.n_features,):
        raise ScftcError(f"{path}: the weights do not have the shape its config describes")
    return net, config
