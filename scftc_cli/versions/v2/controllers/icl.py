"""``icl_adaptive`` on ``scftc-v2``: integral concurrent learning (Parikh, Kamalapurkar & Dixon,
IJACSP 2019, arXiv 1512.03464) of each wheel's ``(g, b, kappa)``, feeding the analytic law through
the estimated allocation (docs/controllers.md, "scftc-v2 ports").

Per wheel ``i`` (``estimators.py`` for the tachometer-measured torque ``z`` and the regressor
``x = [a, 1, s]``): the integral form of the regression over a window of ``window`` steps is the
window mean, ``U_j = mean z = Y_j [g, b, kappa]'`` with ``Y_j = [mean a, 1, mean s]`` (windows with
a clipped or speed-limited sample are skipped). A history stack of ``stack_size`` windows is filled
and then curated (Chowdhary & Johnson 2011): a new window replaces the stored one whose replacement
most increases ``lambda_min`` of the information matrix ``M = sum_j Y_j Y_j'``. While the wheel's
speed has kept its sign, offset and friction are collinear (``s = +-1`` throughout) and
``lambda_min(M) = 0`` for every choice; the score is then that of the ``[a, 1]`` block (v1's
criterion), weighted 1e-3 so that a window that separates friction from offset always wins. The
update, at the control step, is

    phi <- phi + Gamma [gamma_cl / lambda_max(M) sum_j Y_j (U_j - Y_j'phi)
                        + gamma_inst x (z - x'phi) / (1 + x'x)]

with the diagonal adaptation gain ``Gamma = diag(1, offset_ratio, friction_ratio)`` (the paper's
``Gamma``; ratios at most 1, so the step stays stable for ``gamma_cl < 2``; it converges in every
excited direction, finite excitation suffices), ``kappa >= 0`` and ``|g| <= g_max``. The ratios
matter while the data have not yet separated gain from offset (commands near one value): they say
which of the two an unexplained torque is first put on. A square-wave dither along the null space of the
estimated wheel array, each level held one window, excites the data for the first ``dither_steps``
steps after the stack (re)opened.

Mid-flight faults: a stack remembers the healthy plant forever, and its term would pull the
estimate back to it. ``estimators.ChangeDetector`` watches the prediction error of each wheel once
its stack is full and pins the estimate (``lambda_min`` of the ``[a, 1]`` block at least
``ARM_LAMBDA``); a change
purges the episode's stacks (data recording restarts, Kamalapurkar et al.'s purging for
switched systems) and restarts the dither.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context
from scftc_cli.sim.elementary import acos_short, cos_short
from scftc_cli.sim.products import split_matvec3, sum_rows
from scftc_cli.sim.rows import CHUNK_ROWS, HEAVY_PARALLEL_MIN_BATCH, run_rows
from scftc_cli.versions.v2.controllers.adaptive import predicted_torque, sample_weight
from scftc_cli.versions.v2.controllers.estimators import (
    ChangeDetector,
    EstimatingPort,
    WheelSample,
    informative,
)
from scftc_cli.versions.v2.controllers.law import KD_S, KP_S2
from scftc_cli.versions.v2.spec import V2

NAME = "icl_adaptive"
ARM_LAMBDA = 0.05
"""The change test watches a wheel once ``lambda_min`` of its stack's ``[a, 1]`` block reaches
this (the stack then pins ``g``: e.g. ten windows whose mean commands spread by 0.07)."""
FRICTION_TIE = 1e-3
"""Weight of the ``[a, 1]`` block's ``lambda_min`` in the curation score (see the docstring)."""


@dataclass(frozen=True)
class ICLParams:
    """Tunable settings (starting values: v1's where they carry over; docs/controllers.md)."""

    window: int = 4
    stack_size: int = 10
    gamma_cl: float = 0.5
    gamma_inst: float = 0.0
    offset_ratio: float = 1.0
    friction_ratio: float = 1.0
    replace_margin: float = 1.0
    dither_amp: float = 0.2
    dither_steps: int = 8
    detect_threshold: float = 0.02
    detect_steps: int = 2
    g_max: float = 5.0
    kp_s2: float = KP_S2
    kd_s: float = KD_S


@numba.njit(cache=True)
def _eig_extremes(
    m11: float, m12: float, m13: float, m22: float, m23: float, m33: float
) -> tuple[float, float]:
    """``(lambda_min, lambda_max)`` of a symmetric 3x3 matrix (the trigonometric closed form, with
    the project's short ``acos`` and ``cos``: ``sim/elementary.acos_short``, ``cos_short``)."""
    q = (m11 + m22 + m33) / 3.0
    p1 = m12 * m12 + m13 * m13 + m23 * m23
    p2 = (m11 - q) ** 2 + (m22 - q) ** 2 + (m33 - q) ** 2 + 2.0 * p1
    if p2 <= 1e-30 * max(q * q, 1e-300):
        return q, q
    p = math.sqrt(p2 / 6.0)
    b11, b22, b33 = (m11 - q) / p, (m22 - q) / p, (m33 - q) / p
    b12, b13, b23 = m12 / p, m13 / p, m23 / p
    r = 0.5 * (b11 * (b22 * b33 - b23 * b23) - b12 * (b12 * b33 - b23 * b13) + b13 * (b12 * b23 - b22 * b13))
    r = min(max(r, -1.0), 1.0)
    phi = acos_short(r) / 3.0
    largest = q + 2.0 * p * cos_short(phi)
    smallest = q + 2.0 * p * cos_short(phi + 2.0 * math.pi / 3.0)
    return smallest, largest


@numba.njit(cache=True)
def _eig2_min(m11: float, m12: float, m22: float) -> float:
    mean = 0.5 * (m11 + m22)
    return mean - math.sqrt(0.25 * (m11 - m22) ** 2 + m12 * m12)


@numba.njit(cache=True)
def _score(m0: float, m1: float, m2: float, m3: float, m4: float, m5: float) -> float:
    """Curation score of the information entries ``(M11, M12, M13, M22, M23, M33)``:
    ``lambda_min(M) + FRICTION_TIE lambda_min`` of the ``[a, 1]`` block."""
    low, _ = _eig_extremes(m0, m1, m2, m3, m4, m5)
    return max(low, 0.0) + FRICTION_TIE * _eig2_min(m0, m1, m3)


@numba.njit(inline="always")
def _score_setup(m11, m12, m13, m22, m23, m33):  # pragma: no cover - compiled
    """``_score`` up to its transcendental calls, for a loop LLVM can vectorize: ``_eig_extremes``'
    ``(q, p, r, degenerate)`` and ``_eig2_min``, the same operations in the same order (the
    quantities of the degenerate case are computed too, and unused: the caller compiles with
    numpy's error model, so a zero ``p`` gives NaN instead of an exception)."""
    q = (m11 + m22 + m33) / 3.0
    p1 = m12 * m12 + m13 * m13 + m23 * m23
    p2 = (m11 - q) ** 2 + (m22 - q) ** 2 + (m33 - q) ** 2 + 2.0 * p1
    degenerate = p2 <= 1e-30 * max(q * q, 1e-300)
    p = math.sqrt(p2 / 6.0)
    b11, b22, b33 = (m11 - q) / p, (m22 - q) / p, (m33 - q) / p
    b12, b13, b23 = m12 / p, m13 / p, m23 / p
    r = 0.5 * (b11 * (b22 * b33 - b23 * b23) - b12 * (b12 * b33 - b23 * b13) + b13 * (b12 * b23 - b22 * b13))
    r = min(max(r, -1.0), 1.0)
    mean = 0.5 * (m11 + m22)
    return q, p, r, degenerate, mean - math.sqrt(0.25 * (m11 - m22) ** 2 + m12 * m12)


@numba.njit(inline="always")
def _score_finish(q, p, r, degenerate, tie):  # pragma: no cover - compiled
    """``_score`` from ``_score_setup``'s figures: ``lambda_min`` by the trigonometric form."""
    if degenerate:
        smallest = q
    else:
        phi = acos_short(r) / 3.0
        smallest = q + 2.0 * p * cos_short(phi + 2.0 * math.pi / 3.0)
    return max(smallest, 0.0) + FRICTION_TIE * tie


@numba.njit(inline="always")
def _store(ys, us, used, e, w, j, y, u):  # pragma: no cover - compiled
    """Window ``(y, u)`` of episode ``e``'s wheel ``w`` into slot ``j`` of its stack."""
    ys[e, w, j, 0] = y[e, w, 0]
    ys[e, w, j, 1] = y[e, w, 1]
    ys[e, w, j, 2] = y[e, w, 2]
    us[e, w, j] = u[e, w]
    used[e, w, j] = True


@numba.njit(inline="always")
def _information(ys, used, e, w):  # pragma: no cover - compiled
    """The information entries ``(M11, M12, M13, M22, M23, M33)`` of the used slots of episode
    ``e``'s stack of wheel ``w`` (``M = sum_j Y_j Y_j'``, slot by slot), and its first free slot
    (-1 when the stack is full)."""
    free = -1
    m11 = m12 = m13 = m22 = m23 = m33 = 0.0
    for j in range(used.shape[2]):
        if not used[e, w, j]:
            if free < 0:
                free = j
            continue
        a, one, s = ys[e, w, j, 0], ys[e, w, j, 1], ys[e, w, j, 2]
        m11 += a * a
        m12 += a * one
        m13 += a * s
        m22 += one * one
        m23 += one * s
        m33 += s * s
    return m11, m12, m13, m22, m23, m33, free


def stack_offer(
    ys: np.ndarray,
    us: np.ndarray,
    used: np.ndarray,
    y: np.ndarray,
    u: np.ndarray,
    offer: np.ndarray,
    margin: float,
) -> None:
    """Offer window ``(y (n, m, 3), u (n, m))`` to the stacks ``ys (n, m, S, 3)``, ``us (n, m, S)``,
    ``used (n, m, S)`` where ``offer`` ``(n, m)``: fill a free slot, else replace the slot whose
    replacement scores best if that beats ``margin`` times the current score. In place; the
    episodes are independent rows (``sim/rows.run_rows``, threaded from ``HEAVY_PARALLEL_MIN_BATCH``)."""
    run_rows(
        _offer_rows,
        ys,
        us,
        used,
        np.ascontiguousarray(y, dtype=np.float64),
        np.ascontiguousarray(u, dtype=np.float64),
        np.ascontiguousarray(offer, dtype=np.bool_),
        float(margin),
        parallel=used.shape[0] >= HEAVY_PARALLEL_MIN_BATCH,
    )


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _offer_rows(ys, us, used, y, u, offer, margin):  # pragma: no cover - compiled
    """``stack_offer``'s loop, chunks of ``CHUNK_ROWS`` episodes per ``prange`` row. A full stack's
    candidates are scored in two passes, the arithmetic of all of them first (``_score_setup``: a
    loop without calls, which LLVM vectorizes), then the two transcendental calls of each and the
    choice (``_score_finish``), into scratch kept per chunk: the bits of scoring each candidate
    through ``_score`` in turn (tests/oracles/v2_icl.py holds that readable form)."""
    n, m, size = used.shape
    for c in numba.prange((n + CHUNK_ROWS - 1) // CHUNK_ROWS):
        qs, ps, rs, ties = np.empty(size), np.empty(size), np.empty(size), np.empty(size)
        degenerate = np.empty(size, dtype=np.bool_)
        for e in range(c * CHUNK_ROWS, min(n, (c + 1) * CHUNK_ROWS)):
            for w in range(m):
                if not offer[e, w]:
                    continue
                i0, i1, i2, i3, i4, i5, free = _information(ys, used, e, w)
                if free >= 0:
                    _store(ys, us, used, e, w, free, y, u)
                    continue
                now = _score(i0, i1, i2, i3, i4, i5)
                na, no, ns = y[e, w, 0], y[e, w, 1], y[e, w, 2]
                for j in range(size):
                    a, one, s = ys[e, w, j, 0], ys[e, w, j, 1], ys[e, w, j, 2]
                    qs[j], ps[j], rs[j], degenerate[j], ties[j] = _score_setup(
                        i0 - a * a + na * na,
                        i1 - a * one + na * no,
                        i2 - a * s + na * ns,
                        i3 - one * one + no * no,
                        i4 - one * s + no * ns,
                        i5 - s * s + ns * ns,
                    )
                best, best_j = -np.inf, -1
                for j in range(size):
                    score = _score_finish(qs[j], ps[j], rs[j], degenerate[j], ties[j])
                    if score > best:
                        best, best_j = score, j
                if best > margin * now + 1e-12:
                    _store(ys, us, used, e, w, best_j, y, u)


def stack_step(
    ys: np.ndarray, us: np.ndarray, used: np.ndarray, phi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(sum_j Y_j (U_j - Y_j'phi) / lambda_max(M) (n, m, 3), lambda_min of the [a, 1] block (n, m))``,
    one episode per row (as ``stack_offer``)."""
    n, m, _ = used.shape
    direction = np.zeros((n, m, 3))
    arm = np.zeros((n, m))
    run_rows(
        _step_rows,
        ys,
        us,
        used,
        np.ascontiguousarray(phi, dtype=np.float64),
        direction,
        arm,
        parallel=n >= HEAVY_PARALLEL_MIN_BATCH,
    )
    return direction, arm


@numba.njit(cache=True, parallel=True)
def _step_rows(ys, us, used, phi, direction, arm):  # pragma: no cover - compiled
    """``stack_step``'s loop, one episode per ``prange`` row, into ``direction`` and ``arm``."""
    n, m, size = used.shape
    for e in numba.prange(n):
        for w in range(m):
            m11, m12, m13, m22, m23, m33, _ = _information(ys, used, e, w)
            for j in range(size):
                if not used[e, w, j]:
                    continue
                a, one, s = ys[e, w, j, 0], ys[e, w, j, 1], ys[e, w, j, 2]
                r = us[e, w, j] - (a * phi[e, w, 0] + one * phi[e, w, 1] + s * phi[e, w, 2])
                direction[e, w, 0] += a * r
                direction[e, w, 1] += one * r
                direction[e, w, 2] += s * r
            _, largest = _eig_extremes(m11, m12, m13, m22, m23, m33)
            scale = 1.0 / max(largest, 1e-9)
            for c in range(3):
                direction[e, w, c] *= scale
            arm[e, w] = _eig2_min(m11, m12, m22)


class ICLAdaptive(Tuned, EstimatingPort):
    """ICL estimate of ``(g, b, kappa)`` per wheel feeding the law; stacks purged on a change."""

    params_type = ICLParams
    tuned_as = (NAME, V2.version)
    params: ICLParams

    def reset(self, n: int, context: Context) -> None:
        p = self.params
        m = self._start(n, context)
        self.phi = np.zeros((n, m, 3))
        self.phi[..., 0], self.phi[..., 2] = 1.0, self.wheels.coulomb_nm / self.wheels.u_max_nm
        self.ys = np.zeros((n, m, p.stack_size, 3))
        self.us = np.zeros((n, m, p.stack_size))
        self.used = np.zeros((n, m, p.stack_size), dtype=bool)
        self.ring = np.zeros((p.window, 4, n, m))  # a, s, z, linear of the last `window` samples
        self.filled = np.zeros(n, dtype=np.int64)  # samples in the ring since the last purge
        self.detector = ChangeDetector(n, m, p.detect_threshold, p.detect_steps)
        self.since = np.zeros(n, dtype=np.int64)
        self.purged = np.zeros(n, dtype=np.int64)  # how often (diagnostics)
        self.armed = np.zeros((n, m), dtype=bool)  # the change test watches these wheels
        self.measured = 0

    @property
    def estimates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(g_hat, b_hat, kappa_hat)`` ``(n, m)`` each."""
        return self.phi[..., 0], self.phi[..., 1], self.phi[..., 2]

    @property
    def dither_hold_steps(self) -> int:  # type: ignore[override]
        """Each dither level is held one window (the integral form averages over it)."""
        return self.params.window

    def _adapt(self, sample: WheelSample) -> None:
        p = self.params
        g_hat, b_hat, kappa_hat = self.estimates
        target, linear, censored = informative(sample, g_hat, b_hat, kappa_hat, self.wheels)
        ok = linear | censored
        slot = self.measured % p.window
        self.ring[slot] = sample.a, sample.s, sample.z, linear
        self.measured += 1
        self.filled += 1
        residual = target - predicted_torque(sample, g_hat, b_hat, kappa_hat)
        changed = self.detector.update(residual, ok, self.armed)
        if changed.any():
            self.used[changed] = False
            self.filled[changed] = 0
            self.since[changed] = 0
            self.purged += changed
        # the window means of a, s and z: the ring's slots added left to right from slot 0
        # (products.sum_rows' order), over the window length
        mean = sum_rows(np.swapaxes(self.ring[:, :3], 0, 1)) / p.window
        whole = (self.ring[:, 3] > 0.5).all(axis=0) & (self.filled >= p.window)[:, None]
        window_y = np.stack((mean[0], np.ones_like(mean[0]), mean[1]), axis=-1)
        stack_offer(self.ys, self.us, self.used, window_y, mean[2], whole, p.replace_margin)
        direction, spread = stack_step(self.ys, self.us, self.used, self.phi)
        # armed where the stack is full and pins the estimate (a stack still filling would be
        # purged by the transient of its own convergence)
        self.armed = (spread >= ARM_LAMBDA) & self.used.all(axis=-1)
        x = sample.regressor()
        # x . phi and x . x as products.split_matvec3's (x0 p0 + x2 p2) + x1 p1, then +0.0
        err = target - split_matvec3(x[..., None, :], self.phi)[..., 0]
        weight = sample_weight(linear, censored)
        inst = (weight * err / (1.0 + split_matvec3(x[..., None, :], x)[..., 0]))[..., None] * x
        rates = np.array([1.0, p.offset_ratio, p.friction_ratio])  # the diagonal adaptation gain
        phi = self.phi + rates * (p.gamma_cl * direction + p.gamma_inst * inst)
        phi[..., 0] = np.clip(phi[..., 0], -p.g_max, p.g_max)
        phi[..., 2] = np.maximum(phi[..., 2], 0.0)
        self.phi = phi
