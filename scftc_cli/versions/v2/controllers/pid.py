"""``pid`` on ``scftc-v2``: the analytic law's PD plus integral action on the fused attitude, with
anti-windup, through the nominal allocation (Schaub & Junkins, sec. 8.4 "integral feedback";
anti-windup by conditional integration and clamping, Astrom & Hagglund, sec. 3.5).

Body torque demand, with the integral state ``z`` (MRP-seconds) and the law's gyroscopic
feed-forward (``law.torque_demand``):

    L = -I0 (Kp sigma + Kd w + Ki z) + w x (I0 w + sum_i Js Omega_i g_i),
    a = allocate(L) through pinv(G), nominal friction feed-forward (law.allocate),
    z <- z + dt sigma    only while no wheel command is clipped (conditional integration) and
                         |sigma| <= integrate_below per axis,
    |I0 Ki z| / u_max <= integral_cap per axis     (clamping).

Fault-unaware, as in v1: the allocation assumes healthy wheels and no offset is estimated. What the
integrator can remove is a constant torque on the hub; two things it cannot: a reversed wheel
(the nominal allocation then has an unstable direction) and the part of the wheel offsets along
the null space of ``G``, ``(1, 1, 1, 1)``, which puts no torque on the hub but spins all four wheels
up together until they reach their speed limit. What it does remove that no other port does is
a gyro-bias step: the PD parks at ``sigma = -(Kd / Kp) b`` (about ``4 (Kd / Kp) |b|`` of pointing
error), the integral drives ``sigma`` to zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v2.controllers.law import (
    KD_S,
    KP_S2,
    AttitudeFuser,
    allocate,
    allocation,
    friction_nm,
    split_observation,
    torque_demand,
    wheels_of,
)
from scftc_cli.versions.v2.spec import V2

NAME = "pid"


@dataclass(frozen=True)
class PIDParams:
    """Tunable settings (starting values: v1's; docs/controllers.md)."""

    kp_s2: float = KP_S2
    kd_s: float = KD_S
    ki_s3: float = 0.002
    integral_cap: float = 0.3
    integrate_below: float = 0.1


class PID(Tuned, Controller):
    """Nominal-allocation MRP PID with anti-windup and the law's feed-forwards (fault-unaware)."""

    params_type = PIDParams
    tuned_as = (NAME, V2.version)
    params: PIDParams

    def reset(self, n: int, context: Context) -> None:
        self.context, self.wheels = context, wheels_of(context)
        self.fuser = AttitudeFuser(n)
        self.gain = np.ones((n, len(self.wheels.spin_axes)))
        self.allocation = allocation(self.gain, self.wheels)
        self.z = np.zeros((n, 3))

    def act(self, obs: np.ndarray) -> np.ndarray:
        p, ctx, wheels = self.params, self.context, self.wheels
        heads, valid, gyro, tach = split_observation(obs)
        sigma = self.fuser.update(heads, valid, gyro, ctx.dt_s)
        integral = ctx.inertia_nominal_kgm2 * p.ki_s3 * self.z
        demand = torque_demand(sigma, gyro, tach, ctx, p.kp_s2, p.kd_s) - integral
        friction = friction_nm(tach, wheels.coulomb_nm, wheels)
        command = allocate(demand, self.allocation, self.gain, friction, 0.0, wheels)
        saturated = (np.abs(command) >= 1.0).any(axis=1, keepdims=True)
        live = ~saturated & (np.abs(sigma) <= p.integrate_below)
        z = np.where(live, self.z + ctx.dt_s * sigma, self.z)
        z_cap = p.integral_cap * wheels.u_max_nm / np.maximum(ctx.inertia_nominal_kgm2 * p.ki_s3, 1e-12)
        self.z = np.clip(z, -z_cap, z_cap)
        return command
