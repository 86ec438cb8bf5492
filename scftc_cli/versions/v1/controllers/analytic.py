"""The analytic law and the three controllers built directly on it: ``pd``, ``teacher``,
``bias_oracle`` (docs/benchmark.md, "What is identifiable").

``u0 = -I0 (Kp sigma + Kd w) / tau_max``; ``a = (u0 - beta_hat) / theta_eff(theta_hat)``. With the
true ``theta = g/f`` this is exactly the inertia-scaled PD ``-f I0 (...)`` divided by the gain.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.errors import UsageError
from scftc_cli.protocol import Context, Controller

KP_S2 = 0.04  # the calibration point of docs/benchmark.md
KD_S = 0.14
THETA_FLOOR = 0.05  # |theta_eff| never below this: a dead axis saturates instead of dividing by 0


def torque_cap_nm(context: Context) -> float:
    """``tau_max``: the body torque per axis at command 1 (``scftc-v1``'s actuators)."""
    if context.tau_max_nm is None:
        raise UsageError(
            f"this controller flies scftc-v1's body-torque actuators, not {context.benchmark_version}'s"
        )
    return context.tau_max_nm


def theta_eff(theta_hat: np.ndarray, floor: float = THETA_FLOOR) -> np.ndarray:
    """``theta_hat`` kept at least ``floor`` away from zero, keeping its sign (0 counts as +)."""
    return np.where(theta_hat >= 0.0, 1.0, -1.0) * np.maximum(np.abs(theta_hat), floor)


def nominal_command(
    obs: np.ndarray, context: Context, kp_s2: float = KP_S2, kd_s: float = KD_S
) -> np.ndarray:
    """``u0 = -I0 (Kp sigma + Kd w) / tau_max`` ``(n, 3)``, unclipped, for ``obs`` ``(n, 6)``.

    Written as two per-axis gain vectors so a step costs three array operations (hot path).
    """
    scale = -context.inertia_nominal_kgm2 / torque_cap_nm(context)
    return (scale * kp_s2) * obs[:, :3] + (scale * kd_s) * obs[:, 3:]


def analytic_command(u0: np.ndarray, theta_hat: np.ndarray, beta_hat: np.ndarray | float = 0.0) -> np.ndarray:
    """``clip((u0 - beta_hat) / theta_eff(theta_hat), -1, 1)``; all ``(n, 3)``."""
    return np.clip((u0 - beta_hat) / theta_eff(theta_hat), -1.0, 1.0)


class PD(Controller):
    """``a = clip(-I0 (Kp sigma + Kd w) / tau_max)`` (Schaub & Junkins; Basilisk ``mrpFeedback``)."""

    def __init__(self, kp_s2: float = KP_S2, kd_s: float = KD_S) -> None:
        self.kp_s2, self.kd_s = kp_s2, kd_s

    def reset(self, n: int, context: Context) -> None:
        self.context = context

    def act(self, obs: np.ndarray) -> np.ndarray:
        return np.clip(nominal_command(obs, self.context, self.kp_s2, self.kd_s), -1.0, 1.0)


class Teacher(Controller):
    """The analytic law with the true ``theta`` and ``beta_hat = 0`` (an upper bound, privileged)."""

    privileged = True
    uses_bias = False

    def reset(self, n: int, context: Context) -> None:
        if context.fault is None:
            raise ValueError("a privileged controller needs the true fault in its context")
        self.context = context
        self.theta_eff = theta_eff(context.fault.theta)  # constant: computed once, not per step
        self.beta = context.fault.beta if self.uses_bias else 0.0

    def act(self, obs: np.ndarray) -> np.ndarray:
        return np.clip((nominal_command(obs, self.context) - self.beta) / self.theta_eff, -1.0, 1.0)


class BiasOracle(Teacher):
    """The analytic law with the true ``theta`` and ``beta`` (an upper bound, privileged)."""

    uses_bias = True
