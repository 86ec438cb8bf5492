"""pd_plus: probe, identify, then fly the inertia-scaled PD with the identified gains.

A worked example of a SCFTC submission. It needs nothing but numpy and the observations:

1. Probe (4 steps, 2 s): command +0.5 on every axis for two steps, then -0.5 for two. The body
   rate the gyro reports responds to the torque actually applied, so the normalized net torque
   of each step, ``dW = [I0 (w_k+1 - w_k) + dt (w x I0 w)] / (tau_max dt) = theta a + beta``,
   gives per axis the effective authority ``theta = g / f`` (sign included) and bias ``beta = b / f``
   from the two probe levels.
2. Control: the inertia-scaled PD ``u0 = -I0 (Kp sigma + Kd w) / tau_max`` divided by the
   identified authority, minus the bias: ``a = (u0 - beta_hat) / theta_hat``.
3. A disturbance observer keeps refining ``beta_hat`` from the same measured net torque, so a
   small error in ``theta_hat`` does not leave a steady pointing offset.

Gains are the spec's calibration point (Kp = 0.04 s^-2, Kd = 0.14 s^-1); the probe amplitude and
observer rate were checked on the train split only.
"""

from __future__ import annotations

import numpy as np

SUBMISSION = {
    "name": "pd_plus",
    "version": "1.0.0",
    "authors": ["SCFTC maintainers"],
    "description": "Probe-then-control: identifies per-axis authority and bias from a 2 s probe, "
    "then flies the inertia-scaled PD divided by the identified authority, with a bias observer.",
    "entry": "PDPlus",
    "license": "MIT",
    "paper_url": None,
    "code_url": None,
}

KP_S2 = 0.04
KD_S = 0.14
PROBE = 0.5  # command of the identification probe, fraction of tau_max
PROBE_STEPS = 4  # +PROBE for half of them, then -PROBE
OBSERVER_RATE = 0.1  # disturbance-observer smoothing (its loop pole is 1 - rate theta / theta_hat)
THETA_FLOOR = 0.05  # never divide by an authority smaller than this (a dead axis saturates)


class PDPlus:
    """Batch-first: ``reset(n, context)``, then ``act(obs (n, 6)) -> commands (n, 3)``."""

    def reset(self, n: int, context: object) -> None:
        self.i0 = np.asarray(context.inertia_nominal_kgm2, dtype=float)  # (3,) nominal inertia
        self.dt_s = float(context.dt_s)
        self.tau_max_nm = float(context.tau_max_nm)
        self.step = 0
        self.prev_omega = np.zeros((n, 3))
        self.prev_command = np.zeros((n, 3))
        self.probe_sum = np.zeros((2, n, 3))  # summed net torque under +PROBE and -PROBE
        self.theta_hat = np.ones((n, 3))
        self.beta_hat = np.zeros((n, 3))

    def _net_torque(self, omega: np.ndarray) -> np.ndarray:
        """``(n, 3)`` normalized torque the last step actually applied: ``theta a + beta``."""
        w = self.prev_omega
        gyro = np.cross(w, self.i0 * w)
        return (self.i0 * (omega - w) + self.dt_s * gyro) / (self.tau_max_nm * self.dt_s)

    def act(self, obs: np.ndarray) -> np.ndarray:
        sigma, omega = obs[:, :3], obs[:, 3:]
        half = PROBE_STEPS // 2
        if self.step > 0:
            net = self._net_torque(omega)
            if self.step <= PROBE_STEPS:
                self.probe_sum[0 if self.step <= half else 1] += net
            else:
                raw = net - self.prev_command * self.theta_hat
                self.beta_hat += OBSERVER_RATE * (raw - self.beta_hat)
        if self.step == PROBE_STEPS:
            plus, minus = self.probe_sum / half
            self.theta_hat = (plus - minus) / (2.0 * PROBE)
            self.beta_hat = (plus + minus) / 2.0
        if self.step < PROBE_STEPS:
            command = np.full_like(omega, PROBE if self.step < half else -PROBE)
        else:
            u0 = -self.i0 * (KP_S2 * sigma + KD_S * omega) / self.tau_max_nm
            sign = np.where(self.theta_hat >= 0.0, 1.0, -1.0)
            theta = sign * np.maximum(np.abs(self.theta_hat), THETA_FLOOR)
            command = np.clip((u0 - self.beta_hat) / theta, -1.0, 1.0)
        self.prev_omega, self.prev_command = omega.copy(), command
        self.step += 1
        return command
