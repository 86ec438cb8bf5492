"""``scftc-v3``'s ``fdir``: the mission law (``analytic.MissionLaw``) with residual-based fault
detection, isolation and recovery, which reports its diagnosis through ``health()``.

Detectors, all on the observation alone (batch-first; each flag needs its condition on
``persist_steps`` consecutive steps and then stays raised: a latch):

- **wheels**: the torque each wheel really applied over the last step, from the tachometers and
  the gyro (``Js (dOmega/dt + g_i . dw/dt)``), less the nominal friction, regressed per wheel on the
  last command by recursive least squares with forgetting: ``y / u_max = g a + d``. A gain
  ``g_hat`` below ``dead_gain`` is *failed* (dead or reversed), off 1 by more than ``gain_tol``
  or an offset ``|d|`` above ``offset_tol`` is *degraded*. Steps where the motor may clip or the
  speed limit cuts it are left out of the regression.
- **rods**: the hub's momentum balance ``f (I0 dw/dt + w x I0 w) - sum_j r_j m_j (e_j x B) =
  -sum_i g_i tau_i - w x h_w``, regressed on the unknown inertia scale ``f`` and rod gains ``r_j``
  by recursive least squares: ``r_hat`` below ``dead_gain`` is *failed*, below ``half_gain`` degraded.
- **heads**: a valid head more than ``head_tol_rad`` from the median of the valid heads is
  degraded; one that repeats its last reading exactly, or every head invalid, is failed.
- **gyro**: the gyro's rate less the rate the heads' median turns at, averaged; above
  ``gyro_tol_rad_s`` on any axis is degraded.
- **magnetometer**: a reading that jumps by more than ``spike_fraction`` of the field's size from
  the last one is a spike; ``spike_count`` of them is degraded.

Recovery: a wheel found failed is probed for ``probe_steps`` (a small square wave, nothing else
on it; again every ``reprobe_steps`` while it looks dead) so that its gain is identified. Wheels
fly through their identified gains (dead below ``dead_gain``) once identified (``adaptive``) with
their identified offsets cancelled; a flagged rod is commanded through its identified gain, and
the rods rest over each window's last ``quiet_rods_s``; a flagged gyro has its estimated bias
removed; a spiking magnetometer's jumps are replaced by the last good reading. The thresholds
are set on the train split (docs/benchmark-v3.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from scftc_cli.protocol import Context
from scftc_cli.sim.mrp import compose, norm2
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, run_rows
from scftc_cli.versions.v2.controllers.law import friction_nm, vote
from scftc_cli.versions.v3.controllers import fdir_fused
from scftc_cli.versions.v3.controllers.analytic import MissionLaw
from scftc_cli.versions.v3.controllers.law import split_observation

HEALTHY, DEGRADED, FAILED = 0, 1, 2


@dataclass(frozen=True)
class Thresholds:
    """The detectors' settings (chosen on the train split).

    ``probe_dead_zone`` also probes a wheel whose gain estimate falls near zero without a failed
    flag: on the train split (100 episodes per cell) it lifts `gain_bias` and `compound` in their
    later windows (71 to 91 %) but costs more on `friction` (87 to 76 %) and `incipient` (89 to
    48 %), whose regressions it perturbs: off.
    """

    persist_steps: int = 20
    rod_persist_steps: int = 200
    rod_dead_gain: float = 0.25
    forgetting: float = 0.99
    rod_forgetting: float = 0.998
    gain_variance_max: float = 3000.0
    rod_variance_max: float = 0.01
    hold_rate_rad_s: float = 3e-4
    dead_gain: float = 0.3
    half_gain: float = 0.5
    gain_tol: float = 0.1
    offset_tol: float = 0.005
    head_tol_rad: float = 60.0 * np.pi / (180.0 * 3600.0)
    gyro_tol_rad_s: float = 6e-5
    gyro_filter: float = 0.995
    spike_fraction: float = 0.3
    spike_count: int = 3
    warmup_steps: int = 40
    adaptive: bool = True
    offset_rate: float = 0.3
    burst_offset: float = 0.03
    probe: float = 0.03
    probe_steps: int = 60
    reprobe_steps: int = 300
    probe_dead_zone: bool = False
    quiet_rods_s: float = 60.0


class Latch:
    """Per-episode, per-unit flags raised after ``persist`` consecutive steps of a condition."""

    def __init__(self, shape: tuple[int, ...], persist: int) -> None:
        self.count = np.zeros(shape, dtype=np.int64)
        self.raised = np.zeros(shape, dtype=bool)
        self.persist = persist

    def update(self, condition: np.ndarray) -> np.ndarray:
        self.count = np.where(condition, self.count + 1, 0)
        self.raised |= self.count >= self.persist
        return self.raised


def rls_update(theta, p, phi, y, forgetting, mask, trace_max):
    """One recursive-least-squares step with forgetting on the rows where ``mask``:
    ``theta (..., d)``, ``p (..., d, d)``, regressor ``phi (..., d)``, measurement ``y (...)``;
    ``p`` is scaled down where its trace exceeds ``trace_max`` (no wind-up when unexcited).
    Returns new ``(theta, p)``: ``K = P phi / (mu + phi' P phi)``, ``theta += K (y - phi' theta)``,
    ``P = (P - K phi' P) / mu`` symmetrized, then scaled by ``min(1, trace_max / trace)``. One numba
    pass over the rows (``fdir_fused.rls_row``), for ``d`` of 2 or 3 (tests/oracles/v3_fdir.py
    holds a readable numpy form, the same bits)."""
    d = theta.shape[-1]
    lead = theta.shape[:-1]
    new_theta, new_p = np.empty(theta.shape), np.empty(p.shape)
    # writable C-ordered copies, whatever came in: the kernel is compiled for one set of types
    _rls_rows(
        np.array(theta, dtype=np.float64).reshape(-1, d),
        np.array(p, dtype=np.float64).reshape(-1, d, d),
        np.array(np.broadcast_to(phi, theta.shape), dtype=np.float64).reshape(-1, d),
        np.array(np.broadcast_to(y, lead), dtype=np.float64).reshape(-1),
        float(forgetting),
        np.array(np.broadcast_to(mask, lead)).reshape(-1),
        float(trace_max),
        new_theta.reshape(-1, d),
        new_p.reshape(-1, d, d),
    )
    return new_theta, new_p


@numba.njit(cache=True)
def _rls_rows(theta, p, phi, y, forgetting, mask, trace_max, out_theta, out_p):  # pragma: no cover
    """``fdir_fused.rls_row`` on every masked row of copies of ``theta`` and ``p``."""
    rows, d = theta.shape
    if d != 2 and d != 3:
        raise ValueError("rls_update is compiled for 2 or 3 parameters")
    x, scratch, th, old_p = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros((3, 3))
    for r in range(rows):
        out_theta[r] = theta[r]
        out_p[r] = p[r]
        if mask[r]:
            for i in range(d):
                x[i] = phi[r, i]
            fdir_fused.rls_row(out_theta[r], out_p[r], x, y[r], forgetting, trace_max, d, scratch, th, old_p)


class FDIR(MissionLaw):
    """The mission law with the residual detectors above; ``health()`` reports their flags."""

    thresholds = Thresholds()
    null_rate_per_s = 0.0  # no null-space drain: on train it made wheels cross zero speed, where
    # an amplified Coulomb friction flips, more often (incipient 65 % without, 55 % with, n = 20)

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        t, m = self.thresholds, self.m
        self.theta = np.zeros((n, m, 2))
        self.theta[..., 0] = 1.0
        self.p = np.broadcast_to(np.diag([1e4, 1e4]), (n, m, 2, 2)).copy()
        self.rod_theta = np.ones((n, 3))
        self.rod_p = np.broadcast_to(np.diag([10.0, 10.0, 10.0]), (n, 3, 3)).copy()
        self.last: dict[str, np.ndarray] | None = None
        self.wheel_failed, self.wheel_degraded = (
            Latch((n, m), t.persist_steps),
            Latch((n, m), t.persist_steps),
        )
        self.rod_failed, self.rod_degraded = (
            Latch((n, 3), t.rod_persist_steps),
            Latch((n, 3), t.rod_persist_steps),
        )
        self.head_failed, self.head_degraded = Latch((n, 3), 3), Latch((n, 3), t.persist_steps)
        self.gyro_flag = Latch((n,), t.persist_steps)
        self.probe_until = np.full((n, m), -1)
        self.offset_fast = np.zeros((n, m))
        self.dead_zone = np.zeros((n, m), dtype=bool)
        self.gyro_bias = np.zeros((n, 3))
        self.spikes = np.zeros(n, dtype=np.int64)
        self.good_field = np.zeros((n, 3))
        self.codes = np.zeros((n, len(context.health_units) or 12), dtype=np.int64)

    # recovery: what the law believes, from the flags
    def wheel_model(self, tach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = self.thresholds
        flagged = self.wheel_failed.raised | self.wheel_degraded.raised
        g_hat = self.theta[..., 0]
        use = flagged | (t.adaptive & (self.p[..., 0, 0] < t.gain_variance_max))
        gain = np.where(
            use, np.where(g_hat < t.dead_gain, np.where(g_hat < -t.dead_gain, g_hat, 0.0), g_hat), 1.0
        )
        offset = np.where((flagged | t.adaptive) & (np.abs(gain) > 0.0), self.offset_fast, 0.0)
        return gain, offset, friction_nm(tach, self.wheels.coulomb_nm, self.wheels)

    def unloading(self, time_left_s: np.ndarray) -> np.ndarray:
        """The rods rest over each window's last ``quiet_rods_s``: a rod fault cannot disturb the
        final dwell, whatever the identification says."""
        return (time_left_s > self.thresholds.quiet_rods_s).astype(float)[:, None]

    def rod_gain(self) -> np.ndarray:
        flagged = self.rod_failed.raised | self.rod_degraded.raised
        r_hat = np.clip(self.rod_theta, -1.0, 1.0)
        return np.where(flagged, np.where(np.abs(r_hat) < 0.25, 0.0, r_hat), 1.0)

    def act(self, obs: np.ndarray) -> np.ndarray:
        heads, valid, gyro, tach, magnetometer, target, left = split_observation(obs)
        clean = obs.copy()
        clean[:, 12:15] = gyro - np.where(self.gyro_flag.raised[:, None], self.gyro_bias, 0.0)
        field = self._magnetometer(magnetometer)
        clean[:, 19:22] = field
        self._heads(heads, valid)
        if self.last is not None:
            self._wheels_and_rods(gyro, tach, field)
            self._gyro(heads, valid, gyro)
        command = super().act(clean)
        probing = self.k - 1 < self.probe_until  # probe a wheel just found failed: dead or reversed?
        square = np.where(((self.k // 4) % 2) == 0, 1.0, -1.0)
        command[:, : self.m] = np.where(probing, self.thresholds.probe * square, command[:, : self.m])
        self.last = {
            "gyro": gyro.copy(), "tach": tach.copy(), "command": command.copy(), "field": field.copy(),
            "heads": heads.copy(), "valid": valid.copy(),
        }  # fmt: skip
        self._codes()
        return command

    def health(self) -> np.ndarray:
        return self.codes.copy()

    # detectors
    def _magnetometer(self, reading: np.ndarray) -> np.ndarray:
        if self.k == 0:
            self.good_field = reading.copy()
            return reading
        size = np.sqrt(norm2(self.good_field))[:, None]
        jump = np.abs(reading - self.good_field) > self.thresholds.spike_fraction * size
        spiked = jump.any(axis=1)
        self.spikes += spiked
        self.good_field = np.where(spiked[:, None], self.good_field, reading)
        return self.good_field

    def _heads(self, heads: np.ndarray, valid: np.ndarray) -> None:
        t = self.thresholds
        median, count = vote(heads, valid)
        off = np.sqrt(norm2(heads - median[:, None, :])) * 4.0 > t.head_tol_rad
        self.head_degraded.update(valid & off & (count == 3)[:, None])
        stuck = np.zeros_like(valid)
        if self.last is not None:
            stuck = valid & self.last["valid"] & np.all(heads == self.last["heads"], axis=2)
        self.head_failed.update(stuck | ~valid)

    def _gyro(self, heads: np.ndarray, valid: np.ndarray, gyro: np.ndarray) -> None:
        assert self.last is not None
        t = self.thresholds
        before, count_before = vote(self.last["heads"], self.last["valid"])
        now, count_now = vote(heads, valid)
        turn = compose(-before, now)  # body rotation over the step (both on the short branch)
        rate = 4.0 * turn / self.context.dt_s
        usable = (count_before == 3) & (count_now == 3) & (norm2(turn) < 1e-4)
        residual = 0.5 * (gyro + self.last["gyro"]) - rate
        a = t.gyro_filter
        self.gyro_bias = np.where(usable[:, None], a * self.gyro_bias + (1 - a) * residual, self.gyro_bias)
        ready = self.k > 4 * t.warmup_steps
        self.gyro_flag.update(ready & (np.abs(self.gyro_bias).max(axis=1) > t.gyro_tol_rad_s))

    def _wheels_and_rods(self, gyro: np.ndarray, tach: np.ndarray, field: np.ndarray) -> None:
        """The wheel and rod detectors' step (module docstring), the state updated in place: each
        wheel's applied torque less the nominal friction, regressed on ``[a, 1]`` where usable, the
        fast offset observer, the wheels' latches and probe schedule; then the rods' momentum
        balance while the hub holds still and a rod torques, and the rods' latches. One compiled
        pass (``fdir_fused.wheel_rod_pass``; tests/oracles/v3_fdir.py holds a readable numpy form,
        the same bits)."""
        assert self.last is not None
        t, w, last, rods = self.thresholds, self.wheels, self.last, self.rods
        axes = np.ascontiguousarray(w.spin_axes, dtype=np.float64)
        rod_axes = np.ascontiguousarray(rods.axes, dtype=np.float64)
        plant = (
            float(w.spin_inertia_kgm2), float(w.u_max_nm), 0.95 * w.omega_max_rad_s, float(w.coulomb_nm),
            float(w.viscous_nms), float(w.omega_linear_rad_s), float(rods.dipole_max_am2), self.context.dt_s,
        )  # fmt: skip
        settings = (
            t.forgetting, t.offset_rate, t.gain_variance_max, t.warmup_steps, t.burst_offset, t.dead_gain,
            t.half_gain, t.probe_dead_zone, t.reprobe_steps, t.probe_steps, t.gain_tol, t.offset_tol,
            t.persist_steps, t.hold_rate_rad_s, t.rod_forgetting ** (1 / 3), t.rod_variance_max,
            t.rod_dead_gain, t.rod_persist_steps,
        )  # fmt: skip
        wheel_state = (
            self.theta, self.p, self.offset_fast, self.wheel_failed.count, self.wheel_failed.raised,
            self.wheel_degraded.count, self.wheel_degraded.raised, self.probe_until, self.dead_zone,
        )  # fmt: skip
        rod_state = (
            self.rod_theta, self.rod_p, self.rod_failed.count, self.rod_failed.raised,
            self.rod_degraded.count, self.rod_degraded.raised,
        )  # fmt: skip
        c = np.ascontiguousarray  # C-ordered, as the pass is compiled for
        readings = (c(gyro), c(last["gyro"]), c(tach), c(last["tach"]), c(last["command"]), c(last["field"]))
        run_rows(
            fdir_fused.wheel_rod_pass, *readings, self.k, axes, rod_axes, *plant,
            *settings, *wheel_state, *rod_state, parallel=gyro.shape[0] >= PARALLEL_MIN_BATCH,
        )  # fmt: skip

    def _codes(self) -> None:
        m = self.m
        codes = self.codes
        codes[:, :m] = np.where(
            self.wheel_failed.raised, FAILED, np.where(self.wheel_degraded.raised, DEGRADED, 0)
        )
        codes[:, m : m + 3] = np.where(
            self.rod_failed.raised, FAILED, np.where(self.rod_degraded.raised, DEGRADED, 0)
        )
        codes[:, m + 3 : m + 6] = np.where(
            self.head_failed.raised, FAILED, np.where(self.head_degraded.raised, DEGRADED, 0)
        )
        codes[:, m + 6] = np.where(self.gyro_flag.raised, DEGRADED, 0)
        codes[:, m + 7] = np.where(self.spikes >= self.thresholds.spike_count, DEGRADED, 0)
