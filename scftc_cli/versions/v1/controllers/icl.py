"""``icl_adaptive``: integral concurrent learning (Parikh, Kamalapurkar & Dixon, "Integral
concurrent learning: adaptive control with parameter convergence using finite excitation",
IJACSP 2019, arXiv 1512.03464), feeding the analytic law.

Per body axis, the dynamics divided by the inertia scale are linear in ``phi = [theta, beta]'``.
Integrated over a window of ``window`` steps (length ``T = window dt``) and divided by ``tau_max T``
this gives the ICL regression, which needs no acceleration measurement:

    U_j = [I0 (w(t) - w(t - T)) + int (w x I0 w)]_i / (tau_max T) = Y_j phi,
    Y_j = [mean of a over the window, 1]

(computed from the per-step measured torque ``dW`` of ``controllers/observer.py``: ``U_j`` is the
window mean of ``dW``). A history stack of ``stack_size`` pairs ``(Y_j, U_j)`` is filled and then
curated: a new window replaces the stored one whose replacement most increases the minimum
eigenvalue of ``M = sum_j Y_j' Y_j`` (Chowdhary & Johnson 2011 singular-value maximization), so the
stack keeps the most exciting data ever seen. The update, discretized at the control step, is

    phi <- phi + gamma_cl / lambda_max(M) sum_j Y_j' (U_j - Y_j phi) + gamma_inst x (dW - x'phi) / (1 + x'x)

with ``x = [a_k, 1]``: the concurrent-learning term (normalized by ``lambda_max(M)`` so the discrete
step is stable for ``gamma_cl < 2``) converges exponentially as soon as ``lambda_min(M) > 0`` —
finite, not persistent, excitation — and the instantaneous gradient term stands in for the
tracking-error term ``Gamma Y' r`` of the paper (the input gain here is the unknown). ``theta``
absorbs the inertia scale (``theta = g/f``), which is what is identifiable. A square-wave dither
(each level held for one window) for the first ``dither_steps`` steps supplies the finite
excitation: windows of a saturated law alone are collinear (``Y = [+-1, 1]``), the known trap.

Control: ``a = clip((u0 - beta_hat) / theta_eff(theta_hat))`` with ``u0`` at the calibration
point and ``|theta_eff| >= theta_floor``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context, Controller
from scftc_cli.sim.products import pairwise_sum
from scftc_cli.versions.v1.controllers.analytic import KD_S, KP_S2, THETA_FLOOR, nominal_command, theta_eff
from scftc_cli.versions.v1.controllers.observer import TorqueMeter, square_dither
from scftc_cli.versions.v1.spec import V1

NAME = "icl_adaptive"


@dataclass(frozen=True)
class ICLParams:
    """Tunable settings (starting values from the literature, docs/controllers.md)."""

    window: int = 4
    stack_size: int = 10
    gamma_cl: float = 0.5
    gamma_inst: float = 0.0
    replace_margin: float = 1.0
    dither_amp: float = 0.2
    dither_steps: int = 8
    theta_floor: float = THETA_FLOOR
    theta_max: float = 5.0
    kp_s2: float = KP_S2
    kd_s: float = KD_S


def eig2(m11: np.ndarray, m12: np.ndarray, m22: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues ``(lambda_min, lambda_max)`` of symmetric 2x2 matrices given elementwise."""
    mean = 0.5 * (m11 + m22)
    rad = np.sqrt(0.25 * (m11 - m22) ** 2 + m12**2)
    return mean - rad, mean + rad


def window_mean(window: np.ndarray) -> np.ndarray:
    """The mean over axis 0 of a ring buffer ``(window, n, 3)``: ``(n, 3)``, in the order of numpy's
    ``mean(0)`` (which the sealed bits came from), written here: the slots added in slot order onto
    +0.0, ``((+0.0 + x0) + x1) + ...``, then divided by their count."""
    total = 0.0 + window[0]
    for row in window[1:]:
        total = total + row
    return total / len(window)


class HistoryStack:
    """Per-axis stack of ``stack_size`` windows ``(y1 = mean a, U)`` (``y2 = 1`` always), batch
    ``(n, 3, stack_size)``, curated to maximize ``lambda_min`` of its information matrix."""

    def __init__(self, n: int, size: int, replace_margin: float) -> None:
        self.y1 = np.zeros((n, 3, size))
        self.u = np.zeros((n, 3, size))
        self.used = np.zeros((n, 3, size), dtype=bool)
        self.count = 0
        self.replace_margin = replace_margin

    def info(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``M = sum_j Y_j'Y_j`` entries ``(n, 3)`` each, the sums over the stack in
        ``products.pairwise_sum``'s order (numpy's ``sum(-1)``, which the sealed bits came from)."""
        w = self.used.astype(float)
        return pairwise_sum(w * self.y1**2), pairwise_sum(w * self.y1), pairwise_sum(w)

    def offer(self, y1: np.ndarray, u: np.ndarray) -> None:
        """Offer a new window ``(n, 3)``: fill free slots first, then replace where it pays."""
        size = self.y1.shape[-1]
        if self.count < size:
            slot = self.count
            self.y1[..., slot], self.u[..., slot], self.used[..., slot] = y1, u, True
            self.count += 1
            return
        m11, m12, m22 = self.info()
        lam_now, _ = eig2(m11, m12, m22)
        # information matrix with slot j replaced by the new window, for every j: (n, 3, size)
        r11 = m11[..., None] - self.y1**2 + y1[..., None] ** 2
        r12 = m12[..., None] - self.y1 + y1[..., None]
        lam_new, _ = eig2(r11, r12, m22[..., None])
        best = np.argmax(lam_new, axis=-1)
        gain = np.take_along_axis(lam_new, best[..., None], -1)[..., 0]
        take = gain > self.replace_margin * lam_now + 1e-12
        onehot = (np.arange(size) == best[..., None]) & take[..., None]
        self.y1 = np.where(onehot, y1[..., None], self.y1)
        self.u = np.where(onehot, u[..., None], self.u)

    def cl_direction(self, theta: np.ndarray, beta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``sum_j Y_j' (U_j - Y_j phi) / lambda_max(M)`` split into its theta and beta parts (the sums
        over the stack in ``products.pairwise_sum``'s order)."""
        w = self.used.astype(float)
        r = w * (self.u - self.y1 * theta[..., None] - beta[..., None])
        _, lam_max = eig2(*self.info())
        norm = np.maximum(lam_max, 1e-9)
        return pairwise_sum(self.y1 * r) / norm, pairwise_sum(r) / norm


class ICLAdaptive(Tuned, Controller):
    """ICL estimate of ``(theta, beta)`` per axis feeding the analytic law."""

    params_type = ICLParams
    tuned_as = (NAME, V1.version)
    params: ICLParams

    def reset(self, n: int, context: Context) -> None:
        p = self.params
        self.context = context
        self.meter = TorqueMeter(context)
        self.stack = HistoryStack(n, p.stack_size, p.replace_margin)
        self.theta_hat = np.ones((n, 3))
        self.beta_hat = np.zeros((n, 3))
        self.window_a = np.zeros((p.window, n, 3))  # ring buffers of the last window's steps
        self.window_dw = np.zeros((p.window, n, 3))
        self.measured = 0
        self.k = 0

    def _adapt(self, dw: np.ndarray, a: np.ndarray) -> None:
        p = self.params
        slot = self.measured % p.window
        self.window_a[slot], self.window_dw[slot] = a, dw
        self.measured += 1
        if self.measured >= p.window:
            self.stack.offer(window_mean(self.window_a), window_mean(self.window_dw))
        d_theta, d_beta = self.stack.cl_direction(self.theta_hat, self.beta_hat)
        eps = (dw - self.theta_hat * a - self.beta_hat) / (1.0 + a * a)
        theta = self.theta_hat + p.gamma_cl * d_theta + p.gamma_inst * a * eps
        self.beta_hat = self.beta_hat + p.gamma_cl * d_beta + p.gamma_inst * eps
        self.theta_hat = np.clip(theta, -p.theta_max, p.theta_max)

    def act(self, obs: np.ndarray) -> np.ndarray:
        p = self.params
        dw, a_prev = self.meter.read(obs)
        if dw is not None and a_prev is not None:
            self._adapt(dw, a_prev)
        u0 = nominal_command(obs, self.context, p.kp_s2, p.kd_s)
        command = np.clip((u0 - self.beta_hat) / theta_eff(self.theta_hat, p.theta_floor), -1.0, 1.0)
        command = square_dither(command, self.k, p.dither_amp, p.dither_steps, p.window)
        self.meter.hold(command)
        self.k += 1
        return command
