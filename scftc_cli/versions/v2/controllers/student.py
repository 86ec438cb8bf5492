"""What ``scftc-v2``'s RMA student reads and how it is set up: the per-wheel features, the
settings stored with its weights (latch, change test, offset observer) and its layout for the
shared network (``baselines/student.py``). The controllers are ``rma.py``'s.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numba
import numpy as np

from scftc_cli.baselines import student
from scftc_cli.baselines.params import committed_weights
from scftc_cli.baselines.student import StudentLayout, StudentNet
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, as_f64, as_flags, run_rows
from scftc_cli.sim.scalars import clip
from scftc_cli.versions.v2.spec import V2

# Per-wheel features, in this order (``wheel_features``).
FEATURES = (
    "a",  # command held over the last step
    "y",  # its measured normalized torque, nominal friction removed
    "da",  # first differences of both
    "dy",
    "a_y",  # sufficient statistics of the fit y = g a
    "a_a",
    "ratio",  # one-step estimates: a y / (a^2 + eps), da dy / (da^2 + eps)
    "ratio_diff",
    "psi",  # nominal friction over the step, units of fC0 (+-1 outside the linear zone)
    "speed",  # wheel speed / Omega_max
    "innovation",  # e / sigma_y of the change test, clipped
    "after_alarm",  # 1 once the change test fired on this wheel
    "clipped",  # 1 where the motor may have clipped the command (the pair is not valid)
    "clip_sign",  # there, sign(y a): the sign of g, whatever its size
    "valid_raw",  # the pair (a, y) was measured and the model holds
    "valid_diff",  # the pair (da, dy) was measured and the friction did not change
)
N_FEATURES = len(FEATURES)
RAW_PAIR = (0, 1, 14)  # (x, y, valid) columns of the least-squares pair y = g x
DIFF_PAIR = (2, 3, 15)
# Features a constant offset shifts: a bias-invariant student (rma_dob's) never reads them.
BIASED_FEATURES = (1, 4, 6, 10)
# Fixed input scaling, about 1 / the spread of each feature over train-split steps.
FEATURE_SCALE = (3.0, 3.0, 10.0, 10.0, 10.0, 10.0, 1.0, 1.0, 1.0, 3.0, 0.2, 1.0, 1.0, 1.0, 1.0, 1.0)
RATIO_EPS = 1e-4  # regularizes the one-step ratios where the command (change) was small
RATIO_CLIP = 4.0
# Strength of the network's prior guess in units of the summed weighted x^2: sigma_y^2 / 0.3^2, a
# prior worth a 1-sigma of about 0.3 on g given a sample's noise (sigma_y ~ 9.5e-4; 1.3e-3 for
# first differences). One sample at a command (change) of 0.01 already outweighs it: after a late
# change the commands are ~0.01, and a prior of 1e-3 held the estimate for tens of steps.
PRIOR_WEIGHT = 1e-5
# log 0.1 and log 3, correctly rounded and written out (a library's log may round differently on
# another CPU and move the clamp of every prior): the prior's magnitude stays in [0.1, 3].
LOG_MAG_MIN, LOG_MAG_MAX = -2.3025850929940455, 1.0986122886681098
CLIP_GUARD = 0.97  # |y - d_hat psi| at or above this: the motor may have clipped the command
SPEED_GUARD = 0.99  # |Omega| / Omega_max at or above this: the motor may have cut the torque
INNOVATION_CLIP = 10.0
OBSERVER_EXCITATION = 0.1  # the observer starts once a wheel's excitation reached this x min_excitation


@dataclass(frozen=True)
class LatchConfig:
    """Per-wheel persistence-of-excitation latch, counted from the wheel's last restart.

    A wheel latches at ``k >= min_steps`` once its excitation (the summed ``x^2`` of the fit's
    valid pairs) reached ``min_excitation`` and the live estimate moved less than ``tolerance *
    max(|g_hat|, 0.1)`` over the last ``window`` steps, or, excitation reached, at ``max_steps``.
    """

    min_steps: int = 10
    max_steps: int = 80
    min_excitation: float = 0.005  # the fit's std error is then ~ sigma_y / sqrt(0.005), about 1.3 %
    window: int = 10
    tolerance: float = 0.02


@dataclass(frozen=True)
class DetectorConfig:
    """The CUSUM change test on the normalized innovation (module docstring)."""

    rho: float = 0.03  # relative error of the gain estimate the test tolerates (a 10 % change is z^2 ~ 11)
    drift: float = 9.0  # z^2 below 9 (3 sigma) drains the statistic
    threshold: float = 40.0
    z2_max: float = 400.0  # caps one sample's weight; a single sample beyond 7 sigma (z^2 > 49) still alarms
    refractory: int = 10  # no second alarm within this many steps of a restart


@dataclass(frozen=True)
class ObserverConfig:
    """Per-wheel recursive least squares of the offset ``b`` and the extra friction ``d``."""

    forgetting: float = 0.98
    # prior 1-sigma of b and d, units of u_max: offsets reach 0.2 on train, extra friction 0.1; the
    # smaller prior on d books an offset seen in one direction of the wheel mostly as b
    prior_sigma_b: float = 0.3
    prior_sigma_d: float = 0.1
    trace_max: float = 0.1  # the priors' trace: no wind-up where only b + d psi is excited


@dataclass(frozen=True)
class StudentConfig:
    """Architecture and deployment settings stored with the weights."""

    hidden: int = 32
    bias_invariant: bool = False  # rma_dob: first differences, no offset-shifted feature
    observer: bool = False  # rma_dob: estimate and cancel offsets and friction per wheel
    dead_below: float = 0.1  # |g_hat| below this: allocated as a dead wheel
    latch: LatchConfig = field(default_factory=LatchConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    observer_config: ObserverConfig = field(default_factory=ObserverConfig)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StudentConfig:
        return cls(
            hidden=int(d["hidden"]),
            bias_invariant=bool(d["bias_invariant"]),
            observer=bool(d["observer"]),
            dead_below=float(d["dead_below"]),
            latch=LatchConfig(**d["latch"]),
            detector=DetectorConfig(**d["detector"]),
            observer_config=ObserverConfig(**d["observer_config"]),
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
"""What the per-wheel student reads (``baselines/student.py`` runs it)."""


def wheel_features(
    a: np.ndarray,
    y: np.ndarray,
    da: np.ndarray,
    dy: np.ndarray,
    psi: np.ndarray,
    speed: np.ndarray,
    innovation: np.ndarray,
    after_alarm: np.ndarray,
    clipped: np.ndarray,
    valid_raw: np.ndarray,
    valid_diff: np.ndarray,
) -> np.ndarray:
    """``(n * m, N_FEATURES)`` features, episode-major then wheel (the order of ``FEATURES``),
    from ``(n, m)`` arrays; the invalid pairs are zeroed (nothing unmodelled reaches the GRU).
    One compiled pass over the episodes (``_feature_rows``; tests/oracles/v2_student.py holds a
    readable numpy form, the same bits)."""
    n, m = np.shape(a)
    out = np.empty((n, m, N_FEATURES))
    run_rows(
        _feature_rows, as_f64(a), as_f64(y), as_f64(da), as_f64(dy), as_f64(psi), as_f64(speed),
        as_f64(innovation), as_f64(after_alarm), as_flags(clipped), as_flags(valid_raw),
        as_flags(valid_diff), out,
        parallel=n >= PARALLEL_MIN_BATCH,
    )  # fmt: skip
    return out.reshape(-1, N_FEATURES)


@numba.njit(inline="always")
def _sign(v):  # pragma: no cover
    """``np.sign``: +-1, +0.0 for either zero, NaN for NaN."""
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    if v == 0.0:
        return 0.0
    return v


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _feature_rows(
    a, y, da, dy, psi, speed, innovation, after_alarm, clipped, valid_raw, valid_diff, out
):  # pragma: no cover
    """``wheel_features`` of every wheel of every episode into ``out`` ``(n, m, F)``, one row at a
    time in the order of ``FEATURES``: the raw pair ``(a, y)`` and the differenced pair
    ``(da, dy)``, each zeroed where invalid (a flag multiplies as 1.0 or 0.0, as numpy casts it),
    ``a y`` and ``a^2`` of the raw pair, each pair's ratio clipped to ``RATIO_CLIP``, ``psi``, the
    speed, the innovation clipped to ``INNOVATION_CLIP``, ``after_alarm``, the clip flag and
    ``sign(y a)`` where clipped (``np.sign``'s: +0.0 for either zero), the two validity flags."""
    for e in numba.prange(a.shape[0]):
        for i in range(a.shape[1]):
            raw, diff = 1.0 if valid_raw[e, i] else 0.0, 1.0 if valid_diff[e, i] else 0.0
            a_r, y_r = a[e, i] * raw, y[e, i] * raw
            da_d, dy_d = da[e, i] * diff, dy[e, i] * diff
            row = out[e, i]
            row[0], row[1], row[2], row[3] = a_r, y_r, da_d, dy_d
            row[4], row[5] = a_r * y_r, a_r * a_r
            row[6] = clip(a_r * y_r / (a_r * a_r + RATIO_EPS), RATIO_CLIP)
            row[7] = clip(da_d * dy_d / (da_d * da_d + RATIO_EPS), RATIO_CLIP)
            row[8], row[9] = psi[e, i], speed[e, i]
            row[10] = clip(innovation[e, i], INNOVATION_CLIP)
            row[11] = after_alarm[e, i]
            row[12] = 1.0 if clipped[e, i] else 0.0
            row[13] = _sign(y[e, i] * a[e, i]) if clipped[e, i] else 0.0
            row[14], row[15] = raw, diff


def load_student(name: str, path: Path | None = None) -> tuple[StudentNet, StudentConfig]:
    """The committed student ``name`` (or the one at ``path``), ready for the kernel (float64)."""
    return student.load_student(path or committed_weights(name, V2.version), LAYOUT, StudentConfig)
