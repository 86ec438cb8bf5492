"""A batched multiplicative extended Kalman filter for ``scftc-v2``: attitude and gyro bias from
three star-tracker heads and a gyro, with per-head fault detection and isolation.

Markley & Crassidis, *Fundamentals of Spacecraft Attitude Determination and Control* (2014),
sec. 6.2 (the MEKF) and ch. 7 (the gyro model). The reference attitude is kept as an MRP
``sigma_hat`` (body relative to inertial, the benchmark's convention); the filter's state is the
body-frame attitude error ``dtheta`` (rad, ``C_true = exp(-[dtheta x]) C_hat``) and the gyro bias
``b`` (rad/s), with covariance ``P`` ``(n, 6, 6)``.

- Propagation over a step with the trapezoid of the last two gyro readings minus the bias
  estimate, ``w_hat = (w_m,k-1 + w_m,k) / 2 - b_hat``:
  ``dtheta' = exp(-[w_hat dt x]) dtheta - dt db``; process noise from the gyro's white noise
  (``sigma_v``, the context's per-sample figure) and a bias random walk ``sigma_u`` (tuned): the
  constant bias of every episode and the bias *step* of the ``gyro_bias`` fault are both tracked.
- Update with every head that is valid, not latched as faulty, and passes its innovation gate;
  they share ``H = [I 0]``, so their mean innovation with ``R / m`` is the batch update.
- Per-head tests: a head whose reading repeats bit for bit is frozen (a noisy head never repeats):
  latched out. A head whose innovation differs from every other head's by more than the gate
  (``|nu_h - nu_j|^2 / 2R``, chi-square with 3 dof) while the others agree is an outlier: it is left
  out of the update, and isolated after ``isolate_after`` consecutive outlier steps (re-admitted
  after ``readmit_after`` consistent ones). The test is between heads, so a filter that is off
  (a gyro-bias step) never isolates a healthy head; that case is the next test's: when every
  head in use fails its gate against the prediction, ``NIS = nu' (P_tt + R)^-1 nu`` above the
  gate, for ``isolate_after`` steps, the filter re-opens its covariance.
- Bias-step detector: a two-sided CUSUM per axis on the normalized fused innovation; an alarm adds
  ``step_inflation^2`` to the bias covariance, so the filter re-learns a changed bias quickly
  instead of at the random walk's pace.
- An outage (no valid head) only propagates: the attitude rides on the gyro minus the bias estimate.

Units: rad, rad/s, s. Shapes: ``n`` episodes; heads ``(n, 3, 3)`` MRP, validity ``(n, 3)``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numba
import numpy as np

from scftc_cli.protocol import SensorKnowledge
from scftc_cli.sim.elementary import arctan, atan, cosine, sine
from scftc_cli.sim.mrp import compose, norm2
from scftc_cli.sim.mrp_fused import compose_row, norm2_row
from scftc_cli.sim.products import chain_entry, matmul, split_dot3, sum_rows
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, as_f64, run_rows
from scftc_cli.sim.scalars import inverse3
from scftc_cli.versions.v2.controllers.law import nearest_branch, nearest_branch_row, rotation_mrp, vote


@dataclass(frozen=True)
class MEKFSettings:
    """The filter's tunable figures (the sensor noise figures come from the context).

    Attributes:
        bias_walk: bias random walk ``sigma_u``, rad/s per sqrt(s).
        gyro_noise_scale: multiplies the context's gyro white noise in the process noise.
        gate: chi-square gate (3 dof) of the head tests (between heads, and against the filter).
        isolate_after: consecutive outlier steps that isolate a head (or consecutive steps of every
            head failing against the prediction that re-open ``P``).
        readmit_after: consecutive passes that re-admit an isolated head.
        step_drift: CUSUM drift ``kappa`` on the normalized fused innovation (per axis).
        step_threshold: CUSUM threshold ``h``; an alarm inflates the bias covariance.
        step_inflation: bias standard deviation added on an alarm, rad/s.
    """

    bias_walk: float = 1e-6
    gyro_noise_scale: float = 1.0
    gate: float = 25.0
    isolate_after: int = 3
    readmit_after: int = 50
    step_drift: float = 1.0
    step_threshold: float = 12.0
    step_inflation: float = 3e-4


@dataclass(frozen=True)
class MEKFFields:
    """``MEKFSettings``' figures as flat ``mekf_*`` fields of a controller's parameters (a base
    of the ``fdir`` parameters of v2 and v4); ``mekf()`` gathers them."""

    mekf_bias_walk: float = MEKFSettings.bias_walk
    mekf_gyro_noise_scale: float = MEKFSettings.gyro_noise_scale
    mekf_gate: float = MEKFSettings.gate
    mekf_isolate_after: int = MEKFSettings.isolate_after
    mekf_readmit_after: int = MEKFSettings.readmit_after
    mekf_step_drift: float = MEKFSettings.step_drift
    mekf_step_threshold: float = MEKFSettings.step_threshold
    mekf_step_inflation: float = MEKFSettings.step_inflation

    def mekf(self) -> MEKFSettings:
        return MEKFSettings(**{f.name: getattr(self, "mekf_" + f.name) for f in fields(MEKFSettings)})


def inv3(m: np.ndarray) -> np.ndarray:
    """Inverse of a stack of 3x3 matrices ``(..., 3, 3)`` by the adjugate (faster than LAPACK
    for small matrices; the callers' matrices are covariances, well conditioned): the cofactors
    over ``det = (a c00 + b c10) + c c20``. One compiled pass (``_inv3_rows``;
    tests/oracles/v2_mekf.py holds a readable numpy form, the same bits)."""
    flat = as_f64(m).reshape(-1, 3, 3)
    out = np.empty_like(flat)
    run_rows(_inv3_rows, flat, out, parallel=len(flat) >= PARALLEL_MIN_BATCH)
    return out.reshape(np.shape(m))


def skew(v: np.ndarray) -> np.ndarray:
    """``[v x]`` ``(n, 3, 3)`` of rows ``(n, 3)``."""
    z = np.zeros(len(v))
    return np.stack(
        (
            np.stack((z, -v[:, 2], v[:, 1]), axis=1),
            np.stack((v[:, 2], z, -v[:, 0]), axis=1),
            np.stack((-v[:, 1], v[:, 0], z), axis=1),
        ),
        axis=1,
    )


def rotation_matrix(phi: np.ndarray) -> np.ndarray:
    """``exp(-[phi x])`` ``(n, 3, 3)``, the DCM of a body rotation by ``phi`` ``(n, 3)`` rad
    (Rodrigues' formula, series below 1e-4 rad; ``sin`` and ``cos`` are ``sim/elementary``'s,
    correctly rounded)."""
    angle2 = norm2(phi)
    angle = np.sqrt(angle2)
    small = angle < 1e-4
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1.0 - angle2 / 6.0, sine(safe) / safe)
    b = np.where(small, 0.5 - angle2 / 24.0, (1.0 - cosine(safe)) / (safe * safe))
    k = skew(phi)
    return np.eye(3) - a[:, None, None] * k + b[:, None, None] * matmul(k, k)


def rotation_vector(sigma: np.ndarray) -> np.ndarray:
    """Rotation vector ``4 atan(|sigma|) sigma / |sigma|`` ``(n, 3)`` rad of small MRPs ``(n, 3)``
    (``atan`` is ``sim/elementary``'s, correctly rounded)."""
    size = np.sqrt(norm2(sigma))
    ratio = np.where(size > 1e-12, 4.0 * arctan(size) / np.where(size > 1e-12, size, 1.0), 4.0)
    return ratio[:, None] * sigma


class MEKF:
    """Attitude and gyro-bias filter of a batch with per-head FDI (module docstring).

    ``step(heads, valid, gyro)`` once per control step returns ``(sigma_hat (n, 3) MRP,
    rate_hat (n, 3) rad/s)``: the filtered attitude and the gyro reading minus the bias estimate.

    Diagnostics kept for the study: ``stuck`` and ``isolated`` ``(n, 3)`` (latched per head),
    ``head_out_step`` ``(n, 3)`` (first step a head was latched out, -1 if never),
    ``bias_alarm_step`` ``(n,)`` (first bias-step alarm, -1 if none), ``bias_alarms`` ``(n,)``.
    """

    def __init__(self, n: int, sensors: SensorKnowledge, dt_s: float, settings: MEKFSettings) -> None:
        self.n, self.dt, self.s = n, dt_s, settings
        self.heads = sensors.star_tracker_heads
        self.r_var = sensors.star_tracker_noise_rad**2
        self.gyro_var = (settings.gyro_noise_scale * sensors.gyro_noise_rad_s) ** 2
        self.bias0_var = sensors.gyro_bias_bound_rad_s**2 / 3.0  # a uniform prior's variance
        self.sigma = np.zeros((n, 3))
        self.bias = np.zeros((n, 3))
        self.P = np.zeros((n, 6, 6))
        self.last_gyro: np.ndarray | None = None
        self.last_heads = np.full((n, self.heads, 3), np.nan)
        self.last_valid = np.zeros((n, self.heads), dtype=bool)
        self.stuck = np.zeros((n, self.heads), dtype=bool)
        self.isolated = np.zeros((n, self.heads), dtype=bool)
        self.fail_run = np.zeros((n, self.heads), dtype=np.int64)
        self.pass_run = np.zeros((n, self.heads), dtype=np.int64)
        self.common_run = np.zeros(n, dtype=np.int64)
        self.cusum = np.zeros((n, 2, 3))
        self.head_out_step = np.full((n, self.heads), -1)
        self.bias_alarm_step = np.full(n, -1)
        self.bias_alarms = np.zeros(n, dtype=np.int64)
        self.used = np.zeros((n, self.heads), dtype=bool)
        self.statistic_log: list[np.ndarray] = []  # the bias-step CUSUM statistic per step
        self.k = 0

    # -- the filter ---------------------------------------------------------------------------

    def _start(self, heads: np.ndarray, valid: np.ndarray) -> None:
        """First step: the attitude from the vote of the valid heads; ``P`` from the head noise
        and the bias prior."""
        aligned = np.stack([nearest_branch(heads[:, h], heads[:, 0]) for h in range(self.heads)], axis=1)
        voted, count = vote(aligned, valid)
        self.sigma = np.where((count > 0)[:, None], voted, 0.0)
        att_var = np.where(count > 0, 4.0 * self.r_var, 1.0)
        self.P[:, :3, :3] = att_var[:, None, None] * np.eye(3)
        self.P[:, 3:, 3:] = self.bias0_var * np.eye(3)

    def _propagate(self, gyro: np.ndarray) -> None:
        """The attitude and covariance over a step: the attitude composed with the step's
        rotation, ``P`` to ``Phi P Phi' + Q`` (symmetrized), the covariance's products in one
        compiled pass (``_propagation_rows``; tests/oracles/v2_mekf.py holds a readable numpy form,
        the same bits)."""
        assert self.last_gyro is not None
        dt = self.dt
        rate = 0.5 * (self.last_gyro + gyro) - self.bias
        phi = rate * dt
        self.sigma = compose(self.sigma, rotation_mrp(phi))
        qu = self.s.bias_walk**2
        noise = (self.gyro_var * dt * dt + qu * dt**3 / 3.0, -qu * dt * dt / 2.0, qu * dt)
        out = np.empty_like(self.P)
        run_rows(
            _propagation_rows, self.P, as_f64(rotation_matrix(phi)), as_f64(phi), float(dt), *noise, out,
            parallel=len(out) >= PARALLEL_MIN_BATCH,
        )  # fmt: skip
        self.P = out

    def _head_tests(
        self, heads: np.ndarray, candidate: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each head's innovation ``nu`` ``(n, h, 3)`` rad (its rotation from the predicted
        attitude, body frame: the head on the branch nearest the estimate, composed with the
        estimate's inverse, as a rotation vector), its normalized squared size against the
        prediction ``nis`` ``(n, h)`` (``S = P_tt + R``), and the inter-head outliers ``(n, h)``
        among the ``candidate`` heads: a head that disagrees with every other candidate head
        (``|nu_h - nu_j|^2 / 2R`` above the gate, chi-square with 3 dof) while at least one other
        candidate is no outlier. Two compiled passes, the rotation vector's ``atan`` that of
        ``sim/elementary`` (correctly rounded: the same bits as the numpy form's
        ``elementary.arctan``; tests/oracles/v2_mekf.py holds that readable form, the same bits)."""
        n, h = len(heads), self.heads
        v, size = np.empty((h, n, 3)), np.empty((h, n))
        parallel = n >= PARALLEL_MIN_BATCH
        run_rows(_branch_rows, as_f64(heads), as_f64(self.sigma), v, size, parallel=parallel)
        nu, nis, outlier = np.empty((n, h, 3)), np.empty((n, h)), np.empty((n, h), dtype=np.bool_)
        run_rows(
            _head_test_rows, v, size, self.P, float(self.r_var), float(2.0 * self.r_var),
            np.ascontiguousarray(candidate, dtype=np.bool_), float(self.s.gate), nu, nis, outlier,
            parallel=parallel,
        )  # fmt: skip
        return nu, nis, outlier

    def _update(self, nu_mean: np.ndarray, count: np.ndarray) -> np.ndarray:
        """Kalman update with the mean innovation of ``count`` heads (rows with ``count == 0`` are
        left alone); returns the normalized fused innovation ``(n, 3)`` (zero where not updated).
        The gain, the covariance (Joseph form) and the correction in one compiled pass
        (``_update_rows``; tests/oracles/v2_mekf.py holds a readable numpy form, the same bits)."""
        live = count > 0
        n = len(live)
        P, dx, z = np.empty_like(self.P), np.empty((n, 6)), np.empty((n, 3))
        run_rows(
            _update_rows, self.P, as_f64(nu_mean), np.ascontiguousarray(count, dtype=np.int64),
            float(self.r_var), P, dx, z, parallel=n >= PARALLEL_MIN_BATCH,
        )  # fmt: skip
        self.P = P
        self.sigma = np.where(live[:, None], compose(self.sigma, rotation_mrp(dx[:, :3])), self.sigma)
        self.bias = self.bias + dx[:, 3:]
        return z

    # -- one control step ---------------------------------------------------------------------

    def step(self, heads: np.ndarray, valid: np.ndarray, gyro: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fold in one observation; returns ``(sigma_hat (n, 3), rate_hat (n, 3))``."""
        s = self.s
        if self.last_gyro is None:
            self._start(heads, valid)
        else:
            self._propagate(gyro)
        self.last_gyro = gyro.copy()

        # frozen heads: a bit-identical repeat of a valid reading
        repeat = valid & self.last_valid & np.all(heads == self.last_heads, axis=2)
        self._latch_out(repeat & ~self.stuck)
        self.stuck |= repeat
        self.last_heads, self.last_valid = heads.copy(), valid.copy()

        candidate = valid & ~self.stuck
        nu, nis, outlier = self._head_tests(heads, candidate)
        self.fail_run = np.where(outlier, self.fail_run + 1, 0)
        self.pass_run = np.where(
            candidate & ~outlier, self.pass_run + 1, np.where(candidate, 0, self.pass_run)
        )
        isolate = ~self.isolated & (self.fail_run >= s.isolate_after)
        self._latch_out(isolate)
        readmit = self.isolated & (self.pass_run >= s.readmit_after)
        self.isolated = (self.isolated | isolate) & ~readmit

        used = candidate & ~self.isolated & ~outlier
        # filter consistency: every head in use fails its gate against the prediction for a while
        # (a gyro-bias step, the end of a long outage): the filter is off, re-open its covariance
        common = used.any(axis=1) & ~(used & (nis <= s.gate)).any(axis=1)
        self.common_run = np.where(common, self.common_run + 1, 0)
        reopen = self.common_run >= s.isolate_after
        if reopen.any():
            spread = sum_rows(norm2(nu) * used) / np.maximum(used.sum(axis=1), 1)
            self.P[reopen, :3, :3] += spread[reopen, None, None] * np.eye(3)
            self.P[reopen, 3:, 3:] += s.step_inflation**2 * np.eye(3)
            self.common_run = np.where(reopen, 0, self.common_run)
        self.used = used
        count = used.sum(axis=1)
        nu_mean = sum_rows(nu * used[:, :, None]) / np.maximum(count, 1)[:, None]
        z = self._update(nu_mean, count)
        self._bias_step_test(z, count > 0)
        self.k += 1
        return self.sigma, gyro - self.bias

    def _latch_out(self, newly: np.ndarray) -> None:
        self.head_out_step = np.where(newly & (self.head_out_step < 0), self.k, self.head_out_step)

    def _bias_step_test(self, z: np.ndarray, live: np.ndarray) -> None:
        """Two-sided CUSUM per axis on the normalized fused innovation; an alarm inflates the bias
        covariance and restarts the sums."""
        s = self.s
        up = np.maximum(0.0, self.cusum[:, 0] + z - s.step_drift)
        down = np.maximum(0.0, self.cusum[:, 1] - z - s.step_drift)
        self.cusum[:, 0] = np.where(live[:, None], up, self.cusum[:, 0])
        self.cusum[:, 1] = np.where(live[:, None], down, self.cusum[:, 1])
        statistic = self.cusum.max(axis=(1, 2))
        self.statistic_log.append(statistic)
        alarm = (statistic > s.step_threshold) & live
        if alarm.any():
            self.P[alarm, 3:, 3:] += s.step_inflation**2 * np.eye(3)
            self.cusum[alarm] = 0.0
            self.bias_alarm_step = np.where(alarm & (self.bias_alarm_step < 0), self.k, self.bias_alarm_step)
            self.bias_alarms += alarm


# ---------------------------------------------------------------------------------------------
# The covariance's algebra compiled. Each matrix product is ``sim/products.py``'s multiply-add
# chain (the first product rounded, then one fused multiply-add per further term, from +0.0), every
# element-wise step is the same IEEE operation as in the numpy form, and a test compares the bits.
# ``error_model="numpy"`` where a kernel divides: a zero divisor gives IEEE's inf or NaN, as in
# numpy, instead of an exception.


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _inv3_rows(m, out):  # pragma: no cover - compiled
    """``inv3`` of every matrix of the stack ``m`` ``(n, 3, 3)`` into ``out``."""
    for row in numba.prange(m.shape[0]):
        inverse3(m[row], out[row])


@numba.njit(cache=True, parallel=True)
def _propagation_rows(P, phi_tt, phi, dt, q_tt, q_tb, q_bb, out):  # pragma: no cover - compiled
    """``Phi P Phi' + Q`` of ``MEKF._propagate`` for every episode into ``out``
    ``(n, 6, 6)``: ``Phi = [[A, B], [0, I]]`` with ``A = phi_tt`` ``(n, 3, 3)`` and ``B = -dt (I -
    [phi x] / 2)``; the noise ``q_tt I``, ``q_tb I``, ``q_bb I`` added to the blocks; symmetrized."""
    for e in numba.prange(P.shape[0]):
        p, a = P[e], phi_tt[e]
        x, y, w = phi[e, 0], phi[e, 1], phi[e, 2]
        s = np.empty((3, 3))  # [phi x], as skew() builds it (+0.0 on the diagonal)
        s[0, 0], s[0, 1], s[0, 2] = 0.0, -w, y
        s[1, 0], s[1, 1], s[1, 2] = w, 0.0, -x
        s[2, 0], s[2, 1], s[2, 2] = -y, x, 0.0
        b = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                b[i, j] = -dt * ((1.0 if i == j else 0.0) - 0.5 * s[i, j])
        ptb, pbb = p[:3, 3:], p[3:, 3:]  # views of P's blocks
        ptb_t = ptb.T
        a_ptt = np.empty((3, 3))
        a_ptb = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                a_ptt[i, j] = chain_entry(a, i, p, j, 3) + chain_entry(b, i, ptb_t, j, 3)
                a_ptb[i, j] = chain_entry(a, i, ptb, j, 3) + chain_entry(b, i, pbb, j, 3)
        a_t, b_t = a.T, b.T
        full = np.empty((6, 6))
        for i in range(3):
            for j in range(3):
                eye = 1.0 if i == j else 0.0
                full[i, j] = (
                    chain_entry(a_ptt, i, a_t, j, 3) + chain_entry(a_ptb, i, b_t, j, 3)
                ) + q_tt * eye
                full[i, 3 + j] = a_ptb[i, j] + q_tb * eye
                full[3 + i, 3 + j] = pbb[i, j] + q_bb * eye
        for i in range(3):
            for j in range(3):
                full[3 + i, j] = full[j, 3 + i]
        for i in range(6):
            for j in range(6):
                out[e, i, j] = 0.5 * (full[i, j] + full[j, i])


@numba.njit(inline="always")
def _innovation_covariance(p, r):  # pragma: no cover - compiled
    """``P[:3, :3] + r I`` of one episode's covariance ``p`` ``(6, 6)``, as numpy adds ``r * eye``
    (``+ 0.0`` off the diagonal), into a new 3x3 array."""
    S = np.empty((3, 3))
    for u in range(3):
        for v in range(3):
            S[u, v] = p[u, v] + r * (1.0 if u == v else 0.0)
    return S


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _update_rows(P, nu_mean, count, r_var, out_p, out_dx, out_z):  # pragma: no cover - compiled
    """``MEKF._update`` for every episode: the new covariance into ``out_p`` (Joseph
    form, symmetrized; unchanged where ``count == 0``), the correction ``dx`` ``(n, 6)`` into
    ``out_dx`` (zero there) and the normalized fused innovation into ``out_z`` ``(n, 3)``. ``S^-1`` by
    the adjugate (``sim/scalars.inverse3``); ``K nu`` as numpy's three-term einsum, ``(p0 + p2) + p1``."""
    for row in numba.prange(P.shape[0]):
        p = P[row]
        live = count[row] > 0
        r = r_var / max(count[row], 1)
        S = _innovation_covariance(p, r)
        s_inv = np.empty((3, 3))
        inverse3(S, s_inv)
        K = np.empty((6, 3))
        for u in range(6):
            for v in range(3):
                K[u, v] = chain_entry(p, u, s_inv, v, 3)
        nu0, nu1, nu2 = nu_mean[row, 0], nu_mean[row, 1], nu_mean[row, 2]
        for u in range(6):
            out_dx[row, u] = split_dot3(K[u, 0], K[u, 1], K[u, 2], nu0, nu1, nu2) if live else 0.0
        if live:
            ikh = np.empty((6, 6))  # I - K H, H = [I 0]
            for u in range(6):
                for v in range(6):
                    eye = 1.0 if u == v else 0.0
                    ikh[u, v] = eye - K[u, v] if v < 3 else eye
            left = np.empty((6, 6))
            for u in range(6):
                for v in range(6):
                    left[u, v] = chain_entry(ikh, u, p, v, 6)
            ikh_t, k_t = ikh.T, K.T
            full = np.empty((6, 6))
            for u in range(6):
                for v in range(6):
                    full[u, v] = chain_entry(left, u, ikh_t, v, 6) + r * chain_entry(K, u, k_t, v, 3)
            for u in range(6):
                for v in range(6):
                    out_p[row, u, v] = 0.5 * (full[u, v] + full[v, u])
        else:
            for u in range(6):
                for v in range(6):
                    out_p[row, u, v] = p[u, v]
        for u in range(3):
            out_z[row, u] = nu_mean[row, u] / np.sqrt(S[u, u]) if live else 0.0


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _branch_rows(heads, sigma, v, size):  # pragma: no cover - compiled
    """``MEKF._head_tests``' innovations up to their ``arctan``: per episode and head, the reading
    on its branch nearest the estimate (``law.nearest_branch_row``), composed with the estimate's
    inverse (``sim/mrp_fused.compose_row``) into ``v`` ``(h, n, 3)``, and its size ``|v|`` into
    ``size`` ``(h, n)``; the same operations in the same order as the numpy functions
    (``law.nearest_branch``, ``mrp.compose``, ``rotation_vector``)."""
    for e in numba.prange(heads.shape[0]):
        r0, r1, r2 = sigma[e, 0], sigma[e, 1], sigma[e, 2]
        for h in range(heads.shape[1]):
            x0, x1, x2 = nearest_branch_row(heads[e, h, 0], heads[e, h, 1], heads[e, h, 2], r0, r1, r2)
            q0, q1, q2 = compose_row(-r0, -r1, -r2, x0, x1, x2)  # after the estimate's inverse
            v[h, e, 0], v[h, e, 1], v[h, e, 2] = q0, q1, q2
            size[h, e] = np.sqrt(norm2_row(q0, q1, q2))


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _head_test_rows(
    v, size, P, r_var, two_r_var, candidate, gate, nu, nis, outlier
):  # pragma: no cover - compiled
    """``MEKF._head_tests`` from ``_branch_rows``' ``v`` and ``size``: the rotation vectors ``nu``
    (``v`` times ``4 atan(size) / size``, ``atan`` of ``sim/elementary``), their ``nis`` against
    ``S = P_tt + r I`` (the three-operand einsum's order: every product ``nu_i S^-1_ij nu_j`` added
    in turn, i then j, to +0.0: einsum adds them from the first product and then to +0.0, which
    differs only in the sign of a zero sum, and that ends +0.0 either way) and the outliers
    (``np.min``'s NaN kept)."""
    heads = v.shape[0]
    for e in numba.prange(v.shape[1]):
        s_inv = np.empty((3, 3))
        inverse3(_innovation_covariance(P[e], r_var), s_inv)
        for h in range(heads):
            ratio = 4.0 * atan(size[h, e]) / size[h, e] if size[h, e] > 1e-12 else 4.0
            for i in range(3):
                nu[e, h, i] = ratio * v[h, e, i]
            total = 0.0
            for i in range(3):
                for j in range(3):
                    total = total + nu[e, h, i] * s_inv[i, j] * nu[e, h, j]
            nis[e, h] = total
        keep = False
        for h in range(heads):
            closest = np.inf
            for g in range(heads):
                pair = np.inf
                if g != h and candidate[e, g]:
                    d0, d1, d2 = (
                        nu[e, h, 0] - nu[e, g, 0],
                        nu[e, h, 1] - nu[e, g, 1],
                        nu[e, h, 2] - nu[e, g, 2],
                    )
                    pair = norm2_row(d0, d1, d2) / two_r_var
                if closest != closest or pair != pair:
                    closest = np.nan
                elif pair < closest:
                    closest = pair
            outlier[e, h] = candidate[e, h] and closest > gate
            keep = keep or (candidate[e, h] and not outlier[e, h])
        for h in range(heads):
            outlier[e, h] = outlier[e, h] and keep
