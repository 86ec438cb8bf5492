"""``fdir`` on ``scftc-v4``: a flight-style fault detection, isolation and recovery controller
composed from what the project already has (docs/benchmark-v4.md, section 6). Deployable.

- **Attitude and gyro bias**: v2's multiplicative extended Kalman filter (``v2/controllers/mekf.py``)
  on the three heads and the gyro: it estimates the gyro's bias (its constant part and a step),
  latches out a frozen or biased head and rides through an outage. The mission law flies its
  filtered attitude and the bias-corrected rate.
- **Wheels**: ``rls_dob``'s per-wheel estimator and disturbance observer (v4's port, its settings
  tuned on v4's train split): each wheel's effectiveness, offset and Coulomb level, the law
  allocating through them (a wheel estimated below ``dead_below`` is dropped).
- **Rods and magnetometer**: v3's ``fdir`` detectors (``v3/controllers/fdir.py``): the rods'
  momentum balance identifies each rod's gain while the hub holds still (a flagged rod is
  commanded through its identified gain, the rods rest over each window's last minute), and a
  spiking magnetometer's jumps are replaced by the last good reading. That compiled pass also runs
  v3's own wheel regression, whose results this controller does not read.
- **Diagnosis** (``health()``, one code per unit of ``spec.UNITS``), each code from the estimate
  the recovery uses, its thresholds calibrated on healthy train flight (``training/fdir.py``):

  - a wheel, from the estimator's latched estimates ``(g, b, kappa)``: *failed* while ``g`` is
    below ``dead_below`` (dead or reversed: the recovery drops it or drives it backwards),
    *degraded* while ``| |g| - 1 |`` exceeds ``gain_tol``, ``|b|`` exceeds ``offset_tol`` or
    ``kappa`` exceeds ``friction_tol`` times the nominal Coulomb level, each for ``persist_steps``
    latched steps; *failed* also while its estimate, latched or not, reads it driving backwards
    (``g`` below ``-REVERSED_BELOW``) for ``persist_steps`` steps: a burst that reverses a wheel
    re-opens the estimator, which finds ``g`` near -1 but seldom latches before the burst ends. A
    wheel once failed stays at least degraded (what it did once it may do again);
  - a head: *failed* while frozen (a bit-identical repeat) or while every head is out for
    ``persist_steps`` steps; *degraded* once the filter isolated it, or after an outage ended;
  - the gyro: *degraded* once the filter's bias-step CUSUM has alarmed (the filter then re-learns
    the bias quickly);
  - a rod and the magnetometer: v3's ``fdir`` codes.

Every figure of ``rls_dob`` is this version's tuned one; the filter's are v2's ``fdir``'s tuned
ones; ``params/fdir.yaml`` of the version holds them all with the calibration's record.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.protocol import Context
from scftc_cli.versions.v2.controllers.estimators import null_dither
from scftc_cli.versions.v2.controllers.mekf import MEKF, MEKFFields
from scftc_cli.versions.v3.controllers import fdir as v3
from scftc_cli.versions.v3.controllers.analytic import MissionLaw
from scftc_cli.versions.v3.controllers.law import MAG, split_observation
from scftc_cli.versions.v4.controllers.rls import RLSDob, V4RLSParams
from scftc_cli.versions.v4.spec import V4

NAME = "fdir"
HEALTHY, DEGRADED, FAILED = v3.HEALTHY, v3.DEGRADED, v3.FAILED
HEADS, VALID, GYRO = slice(0, 9), slice(9, 12), slice(12, 15)  # the observation's columns
REVERSED_BELOW = 0.5
"""A wheel estimated below ``-REVERSED_BELOW`` drives backwards (half a reversed wheel's gain)."""


@dataclass(frozen=True)
class FDIRParams(MEKFFields, V4RLSParams):
    """``rls_dob``'s settings, the filter's (``mekf_*``) and the detectors' thresholds.

    ``gain_tol``, ``offset_tol`` (of ``u_max``) and ``friction_tol`` (times the nominal Coulomb
    level) start at the truth's tolerances (``plant.health_*_tolerance``: within them a wheel
    counts healthy); the calibration raises each to its margin over healthy train flight.
    """

    gain_tol: float = V4.plant.health_gain_tolerance
    offset_tol: float = V4.plant.health_offset_tolerance
    friction_tol: float = V4.plant.health_friction_tolerance
    persist_steps: int = 20


class FDIR(RLSDob, v3.FDIR):
    """The composition of the module docstring: ``rls_dob``'s estimator, observer, allocation and
    law gains (``RLSDob``), v3's rod and magnetometer detectors and rod recovery (``v3.FDIR``), v2's
    filter in front of the law (``corrected``), and this version's diagnosis (``_diagnose``)."""

    params_type = FDIRParams
    tuned_as = (NAME, V4.version)
    params: FDIRParams
    null_rate_per_s = MissionLaw.null_rate_per_s  # rls_dob's law, not v3 fdir's (which has none)

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)  # rls_dob's estimator, then v3 fdir's detectors, then the law
        assert context.sensors is not None
        self.filter = MEKF(n, context.sensors, context.dt_s, self.params.mekf())
        self.estimate = (np.zeros((n, 3)), np.zeros((n, 3)))  # the filter's (attitude, rate)
        m = self.m
        self.wheel_count = np.zeros((n, m, 2), dtype=np.int64)  # persistence of (failed, degraded)
        self.wheel_now = np.zeros((n, m), dtype=np.int64)
        self.wheel_ever_failed = np.zeros((n, m), dtype=bool)
        self.reversed_run = np.zeros((n, m), dtype=np.int64)
        self.outage_run = np.zeros(n, dtype=np.int64)
        self.outage_seen = np.zeros(n, dtype=bool)

    def corrected(self, obs: np.ndarray) -> np.ndarray:
        """The law flies the filter's attitude (as three agreeing heads) and bias-corrected rate."""
        sigma, rate = self.estimate
        clean = obs.copy()
        clean[:, HEADS] = np.tile(sigma, 3)
        clean[:, VALID] = 1.0
        clean[:, GYRO] = rate
        return clean

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Filter, detectors and estimator on the raw readings, then the law on the corrected ones;
        then ``rls_dob``'s null-space dither and the diagnosis."""
        p, m = self.params, self.m
        heads, valid, gyro, tach, magnetometer, *_ = split_observation(obs)
        sigma, rate = self.filter.step(heads, valid, gyro)
        self.estimate = (sigma.copy(), rate.copy())
        field = self._magnetometer(magnetometer)
        if self.last is not None:
            self._wheels_and_rods(gyro, tach, field)
        sample = self.meter.read(gyro, tach)
        if sample is not None:
            self.rls.update(sample, self.k, self.since)
        clean = obs.copy()
        clean[:, MAG] = field
        command = MissionLaw.act(self, clean)  # through corrected(), rls_dob's model, v3's rods
        wheels = null_dither(command[:, :m], self.since, p.dither_amp, p.dither_steps, self.rls.phi[..., 0])
        self.meter.hold(wheels)
        self.since += 1
        command[:, :m] = wheels
        self.last = {
            "gyro": gyro.copy(),
            "tach": tach.copy(),
            "command": command.copy(),
            "field": field.copy(),
        }
        self._diagnose(valid)
        return command

    def _diagnose(self, valid: np.ndarray) -> None:
        """This step's codes (module docstring), into ``self.codes``."""
        p, m, codes = self.params, self.m, self.codes
        g, b, kappa = self.estimates
        latched = self.rls.latched
        conditions = np.stack(
            (
                g < p.dead_below,
                (np.abs(np.abs(g) - 1.0) > p.gain_tol)
                | (np.abs(b) > p.offset_tol)
                | (kappa * self.wheels.u_max_nm > p.friction_tol * self.wheels.coulomb_nm),
            ),
            axis=-1,
        )
        # persistence counted over latched steps only; an open estimator holds the last code
        self.wheel_count = np.where(
            latched[..., None], np.where(conditions, self.wheel_count + 1, 0), self.wheel_count
        )
        held = self.wheel_count >= p.persist_steps
        now = np.where(held[..., 0], FAILED, np.where(held[..., 1], DEGRADED, HEALTHY))
        self.wheel_now = np.where(latched, now, self.wheel_now)
        self.reversed_run = np.where(g < -REVERSED_BELOW, self.reversed_run + 1, 0)
        backwards = self.reversed_run >= p.persist_steps  # read on every step, latched or not
        wheel = np.where(backwards, FAILED, self.wheel_now)
        self.wheel_ever_failed |= wheel == FAILED
        codes[:, :m] = np.maximum(wheel, np.where(self.wheel_ever_failed, DEGRADED, HEALTHY))
        # rods and magnetometer: v3 fdir's
        codes[:, m : m + 3] = np.where(
            self.rod_failed.raised, FAILED, np.where(self.rod_degraded.raised, DEGRADED, HEALTHY)
        )
        codes[:, m + 7] = np.where(self.spikes >= self.thresholds.spike_count, DEGRADED, HEALTHY)
        # heads: the filter's tests, and outages
        f = self.filter
        out = ~valid.any(axis=1)
        self.outage_run = np.where(out, self.outage_run + 1, 0)
        lasting = self.outage_run >= p.persist_steps
        self.outage_seen |= lasting
        codes[:, m + 3 : m + 6] = np.where(
            f.stuck | lasting[:, None],
            FAILED,
            np.where((f.head_out_step >= 0) | self.outage_seen[:, None], DEGRADED, HEALTHY),
        )
        # gyro: the filter's bias-step alarm
        codes[:, m + 6] = np.where(f.bias_alarms > 0, DEGRADED, HEALTHY)
