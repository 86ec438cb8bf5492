"""Batch rigid-body attitude dynamics: Euler's equations and MRP kinematics, RK4 per step.

This is the reference path of the benchmark: classic RK4 over each zero-order-hold step followed
by the MRP shadow-set switch, which is what Basilisk's ``spacecraft`` hub does (SPEC section 1).
All arrays are batch-first: ``sigma``, ``omega_rad_s``, ``torque_nm``, ``inertia_kgm2`` are
``(n, 3)`` (the inertia is diagonal, one row per episode).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from scftc_cli.sim.mrp import dot, norm2, shadow_switch


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of ``(n, 3)`` arrays (faster than ``np.cross`` for small rows)."""
    return np.stack(
        (
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ),
        axis=1,
    )


def derivatives(
    sigma: np.ndarray, omega_rad_s: np.ndarray, torque_nm: np.ndarray, inertia_kgm2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``sigma_dot = 1/4 [(1-|s|^2) w + 2 s x w + 2 s (s.w)]`` and ``I w_dot = tau - w x I w``."""
    s2, sw = norm2(sigma)[:, None], dot(sigma, omega_rad_s)[:, None]
    sigma_dot = 0.25 * ((1.0 - s2) * omega_rad_s + 2.0 * cross(sigma, omega_rad_s) + 2.0 * sigma * sw)
    omega_dot = (torque_nm - cross(omega_rad_s, inertia_kgm2 * omega_rad_s)) / inertia_kgm2
    return sigma_dot, omega_dot


def rk4_step(
    sigma: np.ndarray,
    omega_rad_s: np.ndarray,
    torque_nm: np.ndarray,
    inertia_kgm2: np.ndarray,
    dt_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One classic RK4 step with the torque held constant, then the shadow-set switch."""
    k1s, k1w = derivatives(sigma, omega_rad_s, torque_nm, inertia_kgm2)
    h = 0.5 * dt_s
    k2s, k2w = derivatives(sigma + h * k1s, omega_rad_s + h * k1w, torque_nm, inertia_kgm2)
    k3s, k3w = derivatives(sigma + h * k2s, omega_rad_s + h * k2w, torque_nm, inertia_kgm2)
    k4s, k4w = derivatives(sigma + dt_s * k3s, omega_rad_s + dt_s * k3w, torque_nm, inertia_kgm2)
    sigma_next = sigma + dt_s / 6.0 * (k1s + 2.0 * k2s + 2.0 * k3s + k4s)
    omega_next = omega_rad_s + dt_s / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
    return shadow_switch(sigma_next), omega_next


class Plant(ABC):
    """A backend: the true state of a batch of episodes, advanced one control step at a time.

    Built from ``sigma0``, ``omega0_rad_s``, ``inertia_kgm2`` (all ``(n, 3)``) and ``dt_s``.
    """

    name: str

    @abstractmethod
    def step(self, torque_nm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Advance one control step under ``torque_nm`` ``(n, 3)``; return the new true state."""

    def actuate(
        self, command: np.ndarray, gain: np.ndarray, bias: np.ndarray, tau_max_nm: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Apply the actuator fault ``tau = (a g + b) tau_max`` to clipped commands ``(n, 3)`` and
        step; returns ``(sigma, omega, |sigma|^2)``. A backend may fuse this into one kernel."""
        sigma, omega = self.step((command * gain + bias) * tau_max_nm)
        return sigma, omega, norm2(sigma)


class NumpyPlant(Plant):
    """The reference backend: every episode of a batch stepped as plain numpy array operations."""

    name = "reference"

    def __init__(
        self, sigma0: np.ndarray, omega0_rad_s: np.ndarray, inertia_kgm2: np.ndarray, dt_s: float
    ) -> None:
        self.sigma, self.omega_rad_s = sigma0.copy(), omega0_rad_s.copy()
        self.inertia_kgm2, self.dt_s = inertia_kgm2, dt_s

    def step(self, torque_nm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Advance one control step under ``torque_nm`` ``(n, 3)``; return the new true state."""
        self.sigma, self.omega_rad_s = rk4_step(
            self.sigma, self.omega_rad_s, torque_nm, self.inertia_kgm2, self.dt_s
        )
        return self.sigma, self.omega_rad_s
