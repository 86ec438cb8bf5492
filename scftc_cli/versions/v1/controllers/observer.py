"""The measured net torque of a step and the disturbance observer built on it.

Dividing the dynamics by the inertia scale ``f`` gives, per body axis ``i``,
``I0 w_dot = tau_max (theta a + beta) - w x (I0 w)``. Integrated over one zero-order-hold step,
the normalized net torque an axis received is measurable from two consecutive rate readings:

    dW_k = [I0 (w_k+1 - w_k) + dt (w x I0 w)]_i / (tau_max dt)  ~=  theta_i a_k + beta_i

(the gyroscopic integral by the trapezoid rule; its error is ~1e-4 in these units at the rates of
the benchmark's transients, far less once settled). Rates are measured by the gyro, which no sensor
fault of the benchmark corrupts, so ``dW`` stays exact up to that rounding even when the star
tracker is biased, dropped or stuck.

The disturbance observer (Chen et al., IEEE TIE 2016; Han, IEEE TIE 2009) low-passes the residual
``dW_k - a_k theta_hat``. At steady state ``beta_hat -> beta theta_hat / theta``, so the feedforward
``-beta_hat / theta_hat`` cancels the true bias even when ``theta_hat`` is wrong (same sign). Its
loop pole is ``1 - lambda theta / theta_hat``: ``lambda`` ~ 0.1 keeps it stable across the envelope.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.protocol import Context
from scftc_cli.sim.mrp import cross
from scftc_cli.versions.v1.controllers.analytic import torque_cap_nm


def gyroscopic_nm(omega_rad_s: np.ndarray, inertia_kgm2: np.ndarray) -> np.ndarray:
    """``w x (I0 w)`` ``(n, 3)`` for rates ``(n, 3)`` and a diagonal inertia ``(3,)`` or ``(n, 3)``."""
    return cross(omega_rad_s, inertia_kgm2 * omega_rad_s)


def measured_torque(omega_prev_rad_s: np.ndarray, omega_rad_s: np.ndarray, context: Context) -> np.ndarray:
    """``dW`` ``(n, 3)``: the normalized net torque (units of ``tau_max``, per unit inertia scale)
    each axis received over the step from ``omega_prev_rad_s`` to ``omega_rad_s`` (both ``(n, 3)``).

    ``dW ~= theta a + beta`` where ``a`` is the (clipped) command held over that step.
    """
    inertia, dt_s = context.inertia_nominal_kgm2, context.dt_s
    gyro = 0.5 * (gyroscopic_nm(omega_prev_rad_s, inertia) + gyroscopic_nm(omega_rad_s, inertia))
    return (inertia * (omega_rad_s - omega_prev_rad_s) + dt_s * gyro) / (torque_cap_nm(context) * dt_s)


class TorqueMeter:
    """Remembers the previous rate and command of a batch so that each ``act`` can read ``dW``.

    Usage per step: ``dW, a_prev = meter.read(obs)`` (``None, None`` on the first step), compute
    the command, then ``meter.hold(command)`` with the command *as clipped* by the simulator.
    """

    def __init__(self, context: Context) -> None:
        self.context = context
        self.omega_prev_rad_s: np.ndarray | None = None
        self.command_prev: np.ndarray | None = None

    def read(self, obs: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
        """``(dW (n, 3), a_prev (n, 3))`` of the step that just ended, for ``obs`` ``(n, 6)``."""
        omega = obs[:, 3:]
        if self.omega_prev_rad_s is None or self.command_prev is None:
            self.omega_prev_rad_s = omega.copy()
            return None, None
        dw = measured_torque(self.omega_prev_rad_s, omega, self.context)
        self.omega_prev_rad_s = omega.copy()
        return dw, self.command_prev

    def hold(self, command: np.ndarray) -> None:
        """Record the clipped command ``(n, 3)`` about to be applied over the next step."""
        self.command_prev = np.clip(command, -1.0, 1.0).copy()


class DisturbanceObserver:
    """Per-axis first-order observer of the effective bias ``beta`` (``(n, 3)`` state).

    ``beta_hat <- (1 - gain) beta_hat + gain (dW - a theta_hat)``.

    Args:
        n: batch size.
        gain: the observer's ``lambda`` in (0, 1]; stability needs ``0 < gain theta/theta_hat < 2``.
    """

    def __init__(self, n: int, gain: float = 0.1) -> None:
        self.gain = gain
        self.beta_hat = np.zeros((n, 3))

    def update(self, dw: np.ndarray, command: np.ndarray, theta_hat: np.ndarray) -> np.ndarray:
        """Fold in one step's ``dW`` ``(n, 3)`` under the held ``command`` ``(n, 3)`` and the current
        ``theta_hat`` ``(n, 3)``; returns ``beta_hat`` ``(n, 3)``."""
        raw = dw - command * theta_hat
        self.beta_hat += self.gain * (raw - self.beta_hat)
        return self.beta_hat


def square_dither(command: np.ndarray, k: int, amp: float, steps: int, hold_steps: int = 1) -> np.ndarray:
    """Add a ``+-amp`` square wave (each level held ``hold_steps`` steps) to ``command`` ``(n, 3)``
    for steps ``k < steps``, first pulling the command into ``[-1 + amp, 1 - amp]`` so that even a
    saturated law yields distinct commands on every axis (the excitation identification needs)."""
    if k >= steps or amp <= 0.0:
        return command
    level = amp if (k // max(hold_steps, 1)) % 2 == 0 else -amp
    return np.clip(np.clip(command, -1.0 + amp, 1.0 - amp) + level, -1.0, 1.0)
