"""Batch rigid-body attitude dynamics: Euler's equations and MRP kinematics, RK4 per step.

This is the reference path of the benchmark: classic RK4 over each zero-order-hold step followed
by the MRP shadow-set switch, which is what Basilisk's ``spacecraft`` hub does (docs/benchmark.md).
All arrays are batch-first: ``sigma``, ``omega_rad_s``, ``torque_nm``, ``inertia_kgm2`` are
``(n, 3)`` (the inertia is diagonal, one row per episode).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Self

import numpy as np

from scftc_cli.sim.mrp import cross, dot, norm2, shadow_switch
from scftc_cli.sim.testbed import Plant
from scftc_cli.versions.v1.spec import V1

if TYPE_CHECKING:
    from scftc_cli.versions.v1.sim.faults import RigidEpisodes


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


class RigidPlant(Plant):
    """A batch of rigid bodies with ``scftc-v1``'s actuator fault ``tau = (a g + b) tau_max``.

    Args:
        sigma0, omega0_rad_s: ``(n, 3)`` initial attitude (MRP) and body rate.
        inertia_kgm2: ``(n, 3)`` diagonal inertia of each episode (``f I0``).
        gain, bias: ``(n, 3)`` per-axis effectiveness and additive bias (fraction of ``tau_max``).
        tau_max_nm: torque per axis at command 1.
        dt_s: control step.
    """

    def __init__(
        self,
        sigma0: np.ndarray,
        omega0_rad_s: np.ndarray,
        inertia_kgm2: np.ndarray,
        gain: np.ndarray,
        bias: np.ndarray,
        tau_max_nm: float,
        dt_s: float,
    ) -> None:
        self.sigma = np.array(sigma0, dtype=np.float64, order="C")
        self.omega_rad_s = np.array(omega0_rad_s, dtype=np.float64, order="C")
        self.inertia_kgm2 = np.ascontiguousarray(inertia_kgm2, dtype=np.float64)
        # own copies: writable whatever the episodes' arrays are (the fused kernel is compiled once)
        self.gain = np.array(gain, dtype=np.float64)
        self.bias = np.array(bias, dtype=np.float64)
        self.tau_max_nm, self.dt_s = float(tau_max_nm), float(dt_s)

    @classmethod
    def of(cls, episodes: RigidEpisodes) -> Self:
        """A plant holding ``episodes``' initial states and faults (the one place that maps an
        episode onto the plant's arguments: ``I = f I0``)."""
        plant, fault = V1.plant, episodes.fault
        inertia = fault.inertia_scale[:, None] * np.asarray(plant.inertia_nominal_kgm2)
        return cls(
            episodes.sigma0,
            episodes.omega0_rad_s,
            inertia,
            fault.gain,
            fault.bias,
            plant.tau_max_nm,
            plant.dt_s,
        )

    def torque_nm(self, command: np.ndarray) -> np.ndarray:
        """``(n, 3)`` body torque the faulty actuators apply for ``command`` ``(n, 3)``."""
        return (command * self.gain + self.bias) * self.tau_max_nm

    def states(self) -> dict[str, np.ndarray]:
        return {"sigma": self.sigma, "omega_rad_s": self.omega_rad_s}


class ReferencePlant(RigidPlant):
    """The reference backend: every episode of a batch stepped as plain numpy array operations."""

    name = "reference"

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Hold ``command`` ``(n, 3)`` over one step; return ``|sigma|^2`` ``(n,)`` of the new state."""
        self.sigma, self.omega_rad_s = rk4_step(
            self.sigma, self.omega_rad_s, self.torque_nm(command), self.inertia_kgm2, self.dt_s
        )
        return norm2(self.sigma)
