"""``pid`` on ``scftc-v3``: the mission law (``analytic.MissionLaw``, fault-unaware like ``pd``) with
v2's ``pid`` integral action on the error to the current window's target.

Body torque demand, with the integral state ``z`` (MRP-seconds):

    L = rate_limited_demand(sigma_BR; Kp, Kd) - I0 Ki z,
    z <- z + dt sigma_BR   only while no wheel command is clipped (conditional integration) and
                           |sigma_BR| <= integrate_below per axis (so a slew never winds it up),
    |I0 Ki z| / u_max <= integral_cap per axis     (clamping).

What an integrator can remove here that the PD cannot: a torque that stays put in the body frame
over a dwell, the unmodelled part of the environment's torques and of a faulty wheel's offset or
rod's dipole (the PD parks at ``sigma = L / (I0 Kp)`` under it), and the offset a gyro-bias step
puts into the fused attitude. ``z`` is kept across windows: what it learned of a body-fixed torque
still holds after a slew.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context
from scftc_cli.versions.v2.controllers.pid import PIDParams
from scftc_cli.versions.v3.controllers.analytic import MissionLaw
from scftc_cli.versions.v3.controllers.fused import rate_limited_demand
from scftc_cli.versions.v3.spec import V3

NAME = "pid"


class PID(Tuned, MissionLaw):
    """The mission law with conditional, clamped integral action (fault-unaware; v2's
    ``PIDParams``: the same five settings, tuned on v3's train split)."""

    params_type = PIDParams
    tuned_as = (NAME, V3.version)
    params: PIDParams

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        self.z = np.zeros((n, 3))

    def demand(self, error: np.ndarray, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        p = self.params
        integral = self.context.inertia_nominal_kgm2 * p.ki_s3 * self.z
        return rate_limited_demand(error, gyro, tach, self.context, p.kp_s2, p.kd_s) - integral

    def commanded(self, error: np.ndarray, wheels: np.ndarray) -> None:
        p, ctx = self.params, self.context
        saturated = (np.abs(wheels) >= 1.0).any(axis=1, keepdims=True)
        live = ~saturated & (np.abs(error) <= p.integrate_below)
        z = np.where(live, self.z + ctx.dt_s * error, self.z)
        z_cap = p.integral_cap * self.wheels.u_max_nm / np.maximum(ctx.inertia_nominal_kgm2 * p.ki_s3, 1e-12)
        self.z = np.clip(z, -z_cap, z_cap)
