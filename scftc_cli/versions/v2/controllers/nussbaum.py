"""``nussbaum`` on ``scftc-v2``: a Nussbaum gain per wheel for the unknown direction of each wheel
(Nussbaum, Syst. Control Lett. 1983; the disturbance term of Ye & Jiang, IEEE TAC 1998; saturated
spacecraft variants e.g. Hu, Shao & Guo, IEEE TAES 2018), on the nominal allocation
(docs/controllers.md, "scftc-v2 ports").

On v2 the unknown control directions are the wheels' (a reversed wheel turns the nominal
allocation's response along its axis negative), so the v1 per-axis law becomes a per-wheel law on
the wheel-space error. With ``P = pinv(G)`` (nominal, ``(m, 3)``) and ``n = (1, 1, 1, 1) / 2``
(the null space of ``G``), per wheel ``i``, in command units:

    s   = -P I0 (Kp sigma + Kd w) / u_max + k_null Js n n' Omega / u_max     (so that a = -s is
          the nominal PD on the hub plus a brake on the wheels' common spin),
    a_ff = -P (w x (I0 w + sum_j Js Omega_j g_j)) / u_max - fr_nominal(Omega) / u_max,
    u_bar = s + d_hat - a_ff,      a = clip(-N(zeta) u_bar),
    zeta  <- zeta + gamma dt dz(s) u_bar / (1 + u_bar^2),
    d_hat <- clip(d_hat + gamma_d dt s / (1 + u_bar^2), -d_max, d_max),
    N(zeta) = zeta^2 cos(zeta) / (zeta0^2 cos zeta0),    zeta(0) = zeta0,

so every wheel starts as the nominal law (``N(zeta0) = 1``). A reversed wheel makes the hub error
grow along its spin axis, which projects three times as strongly on its own wheel as on the others
(``g_j . g_i = -1/3``); its ``zeta`` sweeps past ``pi/2`` first and its gain changes sign. ``d_hat``
integrates the wheel-space error: a constant offset per wheel, including its component along the
null space of ``G`` that puts no torque on the hub, which the ``k_null`` term makes visible in
``s`` (without it the wheels spin up together until they saturate, the failure the docs of the
allocation describe). Fused attitude, gyro and tachometers from ``law.py``; no identification, no
use of the wheel-torque measurement (the method's point is to need none).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context, Controller
from scftc_cli.sim.elementary import cosine
from scftc_cli.sim.mrp import cross
from scftc_cli.sim.products import matmul
from scftc_cli.versions.v2.controllers.law import (
    KD_S,
    KP_S2,
    AttitudeFuser,
    allocation,
    friction_nm,
    split_observation,
    wheels_of,
)
from scftc_cli.versions.v2.spec import V2

NAME = "nussbaum"


@dataclass(frozen=True)
class NussbaumParams:
    """Tunable settings (starting values: v1's where they carry over; docs/controllers.md)."""

    gamma: float = 0.05
    zeta0: float = 1.0
    dead_zone: float = 0.01
    gamma_d: float = 0.0
    d_max: float = 2.0
    k_null: float = 0.01
    kp_s2: float = KP_S2
    kd_s: float = KD_S


def nussbaum_gain(zeta: np.ndarray, zeta0: float) -> np.ndarray:
    """``N(zeta) = zeta^2 cos(zeta)``, scaled so that ``N(zeta0) = 1``; any shape. ``cos`` is
    ``elementary.cosine`` (correctly rounded), the squares products ``x * x``."""
    return zeta * zeta * cosine(zeta) / (zeta0 * zeta0 * cosine(zeta0))


class Nussbaum(Tuned, Controller):
    """Per-wheel ``a = -N(zeta) (s + d_hat - a_ff)`` with ``zeta`` and ``d_hat`` adapted from ``s``."""

    params_type = NussbaumParams
    tuned_as = (NAME, V2.version)
    params: NussbaumParams

    def reset(self, n: int, context: Context) -> None:
        self.context, self.wheels = context, wheels_of(context)
        m = len(self.wheels.spin_axes)
        self.fuser = AttitudeFuser(n)
        self.pinv = allocation(np.ones((1, m)), self.wheels)[0]  # (m, 3)
        null = np.full(m, 1.0 / np.sqrt(m))
        self.null_projector = np.outer(null, null)
        self.zeta = np.full((n, m), self.params.zeta0)
        self.d_hat = np.zeros((n, m))

    def act(self, obs: np.ndarray) -> np.ndarray:
        p, ctx, wheels = self.params, self.context, self.wheels
        heads, valid, gyro, tach = split_observation(obs)
        sigma = self.fuser.update(heads, valid, gyro, ctx.dt_s)
        inertia, u_max, js = ctx.inertia_nominal_kgm2, wheels.u_max_nm, wheels.spin_inertia_kgm2
        hub = matmul(inertia * (p.kp_s2 * sigma + p.kd_s * gyro), self.pinv.T)
        s = -hub / u_max + p.k_null * js * matmul(tach, self.null_projector) / u_max
        momentum = inertia * gyro + matmul(js * tach, wheels.spin_axes)
        feed_forward = -matmul(cross(gyro, momentum), self.pinv.T) / u_max
        feed_forward -= friction_nm(tach, wheels.coulomb_nm, wheels) / u_max
        u_bar = s + self.d_hat - feed_forward
        command = np.clip(-nussbaum_gain(self.zeta, p.zeta0) * u_bar, -1.0, 1.0)
        dz = np.sign(s) * np.maximum(np.abs(s) - p.dead_zone, 0.0)
        self.zeta = self.zeta + p.gamma * ctx.dt_s * dz * u_bar / (1.0 + u_bar**2)
        self.d_hat = np.clip(self.d_hat + p.gamma_d * ctx.dt_s * s / (1.0 + u_bar**2), -p.d_max, p.d_max)
        return command
