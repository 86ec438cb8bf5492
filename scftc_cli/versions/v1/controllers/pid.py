"""``pid``: the inertia-scaled MRP PD plus integral action on sigma, with anti-windup (Schaub &
Junkins, *Analytical Mechanics of Space Systems*, sec. 8.4 "integral feedback"; Basilisk
``mrpFeedback``; anti-windup by conditional integration and clamping, Astrom & Hagglund,
*Advanced PID Control*, sec. 3.5).

Per body axis, with the integral state ``z`` (MRP-seconds):

    a = clip(-I0 (Kp sigma + Kd w + Ki z) / tau_max)
    z <- z + dt sigma     only where the axis is not saturated-and-pushing-further
                          (conditional integration) and ``|sigma| <= integrate_below``,
    |I0 Ki z / tau_max| <= integral_cap                       (clamping)

The integrator removes a constant bias (the PD alone parks at ``sigma_ss = b tau_max / (g I0 Kp)``).
Its small-angle loop ``s^3 + theta Kd s^2 + theta Kp/4 s + theta Ki/4`` is unstable once
``Ki > theta Kd Kp``, and low authority or saturation lowers the effective ``theta``: the expected
failure is a limit cycle against the cap at the strict dwell gate. PID is fault-unaware: a
reversed axis is positive feedback, so no gain set settles the held-out sign patterns (2-3
reversed axes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v1.controllers.analytic import KD_S, KP_S2, torque_cap_nm
from scftc_cli.versions.v1.spec import V1

NAME = "pid"


@dataclass(frozen=True)
class PIDParams:
    """Tunable settings (starting values from the literature, docs/controllers.md)."""

    kp_s2: float = KP_S2
    kd_s: float = KD_S
    ki_s3: float = 0.002
    integral_cap: float = 0.3
    integrate_below: float = 0.1


class PID(Tuned, Controller):
    """Inertia-scaled MRP PID with anti-windup (fault-unaware)."""

    params_type = PIDParams
    tuned_as = (NAME, V1.version)
    params: PIDParams

    def reset(self, n: int, context: Context) -> None:
        self.context = context
        self.z = np.zeros((n, 3))

    def act(self, obs: np.ndarray) -> np.ndarray:
        p, ctx = self.params, self.context
        sigma, omega = obs[:, :3], obs[:, 3:]
        scale = ctx.inertia_nominal_kgm2 / torque_cap_nm(ctx)
        u = -scale * (p.kp_s2 * sigma + p.kd_s * omega + p.ki_s3 * self.z)
        command = np.clip(u, -1.0, 1.0)
        # integrating sigma > 0 pushes u down: freeze where that deepens a saturation
        pushing = ((u <= -1.0) & (sigma > 0.0)) | ((u >= 1.0) & (sigma < 0.0))
        live = ~pushing & (np.abs(sigma) <= p.integrate_below)
        z = np.where(live, self.z + ctx.dt_s * sigma, self.z)
        z_cap = p.integral_cap / np.maximum(scale * p.ki_s3, 1e-12)
        self.z = np.clip(z, -z_cap, z_cap)
        return command
