"""``nussbaum``: a Nussbaum-gain law for unknown control direction, per axis (Nussbaum, "Some
remarks on a conjecture in parameter adaptive control", Syst. Control Lett. 1983; for spacecraft
attitude with input saturation see e.g. Hu, Shao & Guo, IEEE TAES 2018, and Chen, Ge et al.).

Per body axis ``i`` with the PD-type sliding variable in command units

    s_i = I0_i (Kp sigma_i + Kd w_i) / tau_max     (so that the nominal PD is ``a = -s``),

the law with adaptive compensation of a constant disturbance (Ye & Jiang, "Adaptive nonlinear
design without a priori knowledge of control directions", IEEE TAC 1998: ``u = N(zeta) u_bar``,
``zeta_dot = gamma s u_bar``, ``d_hat_dot = gamma_d s``) is

    u_bar_i = s_i + d_hat_i,        a_i = clip(-N(zeta_i) u_bar_i),
    zeta_i <- zeta_i + gamma dt dz(s_i) u_bar_i / (1 + u_bar_i^2),
    d_hat_i <- clip(d_hat_i + gamma_d dt s_i / (1 + u_bar_i^2), -d_max, d_max),
    N(zeta) = zeta^2 cos(zeta) / (zeta0^2 cos(zeta0)),   zeta_i(0) = zeta0 in (0, pi/2),

so every axis starts as the nominal PD (``N(zeta0) = 1``). On a reversed axis the error grows,
``zeta`` sweeps past ``pi/2`` and the gain changes sign with growing amplitude until it matches the
true direction (the Nussbaum property: ``sup`` and ``inf`` of ``(1/z) int_0^z N`` are ``+-inf``).
``d_hat`` is the adaptive estimate of the bias (an integral of ``s`` routed through ``N``, so it
works whichever the direction; no dead-zone on it, which would park the axis at the dead-zone's
edge); ``gamma_d = 0`` gives the plain law. ``dz`` is a dead-zone
(``dz(s) = sign(s) max(|s| - dead_zone, 0)``) so a settled axis stops adapting ``zeta``, and both
updates are normalized by ``1 + u_bar^2`` so a large initial error cannot race ``zeta`` through
several sign changes in one swing (nor wind ``d_hat`` up): two standard robustness modifications
under input saturation, which breaks the textbook Lyapunov lemma. Large transients while ``zeta``
sweeps are the known price, which the dwell gate punishes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v1.controllers.analytic import KD_S, KP_S2, torque_cap_nm
from scftc_cli.versions.v1.spec import V1

NAME = "nussbaum"


@dataclass(frozen=True)
class NussbaumParams:
    """Tunable settings (starting values from the literature, docs/controllers.md)."""

    gamma: float = 0.05
    zeta0: float = 1.0
    dead_zone: float = 0.01
    gamma_d: float = 0.0
    d_max: float = 2.0
    kp_s2: float = KP_S2
    kd_s: float = KD_S


def nussbaum_gain(zeta: np.ndarray, zeta0: float) -> np.ndarray:
    """``N(zeta) = zeta^2 cos(zeta)``, scaled so that ``N(zeta0) = 1``; any shape."""
    return zeta**2 * np.cos(zeta) / (zeta0**2 * np.cos(zeta0))


class Nussbaum(Tuned, Controller):
    """Per-axis ``a = -N(zeta) (s + d_hat)`` with ``zeta`` and ``d_hat`` adapted from ``s``."""

    params_type = NussbaumParams
    tuned_as = (NAME, V1.version)
    params: NussbaumParams

    def reset(self, n: int, context: Context) -> None:
        self.context = context
        self.zeta = np.full((n, 3), self.params.zeta0)
        self.d_hat = np.zeros((n, 3))

    def act(self, obs: np.ndarray) -> np.ndarray:
        p, ctx = self.params, self.context
        s = ctx.inertia_nominal_kgm2 * (p.kp_s2 * obs[:, :3] + p.kd_s * obs[:, 3:]) / torque_cap_nm(ctx)
        u_bar = s + self.d_hat
        command = np.clip(-nussbaum_gain(self.zeta, p.zeta0) * u_bar, -1.0, 1.0)
        dz = np.sign(s) * np.maximum(np.abs(s) - p.dead_zone, 0.0)
        self.zeta = self.zeta + p.gamma * ctx.dt_s * dz * u_bar / (1.0 + u_bar**2)
        self.d_hat = np.clip(self.d_hat + p.gamma_d * ctx.dt_s * s / (1.0 + u_bar**2), -p.d_max, p.d_max)
        return command
