"""``rls_dob`` on ``scftc-v3``: v2's estimate-then-control port (``versions/v2/controllers/rls.py``)
flying the mission law (``analytic.MissionLaw``).

Per wheel, every step, exactly v2's estimator: each wheel's torque over the last step from the
tachometers and the gyro (``WheelTorqueMeter``, the ``ramp`` friction model), recursive least
squares with forgetting on ``z = [a, 1, s] [g, b, kappa]'``, latched once ``g_hat`` is still, then
a disturbance observer carrying the offset; a residual test re-opens every wheel of the episode
when a fault starts, comes back or creeps past the threshold after the latch closed
(``rls_step``). The wheel measurement does not see the environment or the rods (they act on the
hub, not between hub and wheel), so v2's estimator carries over unchanged.

What the mission law gets from it: the estimated gains (a wheel estimated dead, ``|g_hat| < 0.1``,
dropped from the allocation, whose pseudo-inverse is v2's closed form in one compiled pass),
offsets and Coulomb levels (``wheel_model``), and the rate-limited PD at the port's gains. After
the law, v2's square-wave dither along the estimated null space for ``dither_steps`` steps after
every (re)opening, and on a wheel estimated dead. The rods unload as
in ``pd`` (this port estimates no rod), and the null-space drain runs through the estimated gains.
It reports no diagnosis (``health`` is not defined: it never alarms).

Every parameter may be an ``(n, 1)`` array, one value per episode, so that the tuner flies a whole
generation of candidates as one batch (``training/tuning.py``).
"""

from __future__ import annotations

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context
from scftc_cli.versions.v2.controllers.estimators import (
    WheelTorqueMeter,
    closed_form_allocation,
    effective_gain,
    null_dither,
)
from scftc_cli.versions.v2.controllers.law import friction_nm
from scftc_cli.versions.v2.controllers.rls import RLSParams, WheelRLS
from scftc_cli.versions.v3.controllers.analytic import MissionLaw
from scftc_cli.versions.v3.controllers.fused import rate_limited_demand
from scftc_cli.versions.v3.controllers.law import split_observation
from scftc_cli.versions.v3.spec import V3

NAME = "rls_dob"


class RLSDob(Tuned, MissionLaw):
    """Estimate-then-control on the mission law: per-wheel RLS of ``(g, b, kappa)``, latched, then
    the observer; a residual test re-opens the latch (v2's ``RLSParams``, tuned on v3's train
    split)."""

    params_type = RLSParams
    tuned_as = (NAME, V3.version)
    params: RLSParams

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        p = self.params
        self.meter = WheelTorqueMeter(context, friction="ramp")
        self.rls = WheelRLS(n, self.m, p, self.wheels)
        self.since = np.zeros(n, dtype=np.int64)  # steps since the estimator (re)opened

    @property
    def estimates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(g_hat, b_hat, kappa_hat)`` ``(n, m)`` each, as the law uses them."""
        return self.rls.estimates

    def wheel_model(self, tach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        g_hat, b_hat, kappa_hat = self.estimates
        gain = effective_gain(g_hat)
        friction = friction_nm(tach, kappa_hat * self.wheels.u_max_nm, self.wheels)
        return gain, np.where(gain == 0.0, 0.0, b_hat), friction

    def allocation(self, gain: np.ndarray) -> np.ndarray:
        """v2's ``rls_dob`` allocation: the closed-form pseudo-inverse of its compiled law."""
        return closed_form_allocation(gain, self.wheels)

    def demand(self, error: np.ndarray, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        return rate_limited_demand(error, gyro, tach, self.context, self.params.kp_s2, self.params.kd_s)

    def act(self, obs: np.ndarray) -> np.ndarray:
        p, m = self.params, self.m
        _, _, gyro, tach, *_ = split_observation(obs)
        sample = self.meter.read(gyro, tach)
        if sample is not None:
            self.rls.update(sample, self.k, self.since)
        command = super().act(obs)  # the law through the estimates (advances self.k)
        wheels = null_dither(command[:, :m], self.since, p.dither_amp, p.dither_steps, self.rls.phi[..., 0])
        self.meter.hold(wheels)
        self.since += 1
        command[:, :m] = wheels
        return command
