"""Shared batches and a small feedback law (PD, rods unloading, rods fed forward) for the v3 tests."""

from __future__ import annotations

import dataclasses

import numpy as np

from scftc_cli.sim.mrp import cross, to_dcm
from scftc_cli.versions.v2.sim.dynamics import friction_torque_nm
from scftc_cli.versions.v3.sim.dynamics import PlantFault, V3Constants, V3PlantBase
from scftc_cli.versions.v3.sim.environment import Environment
from tests.versions.v3.sim.demo import random_faults

CONSTANTS = V3Constants()
WHEELS = CONSTANTS.wheels
M_MAX = CONSTANTS.environment.rod_dipole_max_am2
OMEGA_MAX = WHEELS.omega_max_rad_s


def wheel_speeds_for(momentum_b: np.ndarray) -> np.ndarray:
    """Minimum-norm wheel speeds ``(n, 4)`` whose momentum ``Js sum_i Omega_i g_i`` is ``momentum_b``
    ``(n, 3)`` N m s (tetrahedral axes: ``G G' = 4/3 I``)."""
    return (0.75 / WHEELS.js_kgm2) * (momentum_b @ WHEELS.axes.T)


def wheel_momentum(wheel_speed_rad_s: np.ndarray) -> np.ndarray:
    """``Js sum_i Omega_i g_i`` ``(n, 3)`` N m s."""
    return (WHEELS.js_kgm2 * wheel_speed_rad_s) @ WHEELS.axes


def inertial_momentum(plant: V3PlantBase) -> np.ndarray:
    """Total angular momentum of hub and wheels, inertial frame ``(n, 3)`` N m s."""
    h_b = np.einsum("nij,nj->ni", plant.mass.total_inertia_kgm2, plant.omega_rad_s) + wheel_momentum(
        plant.wheel_speed_rad_s
    )
    return np.einsum("nji,nj->ni", to_dcm(plant.sigma), h_b)


def quiet(env: Environment) -> Environment:
    """``env`` with no residual dipole and no solar pressure."""
    n = env.n
    return dataclasses.replace(env, residual_dipole_am2=np.zeros((n, 3)), facet_area_m2=np.zeros(n))


def command(
    plant: V3PlantBase,
    working: np.ndarray | None = None,
    unload_gain: float = 0.0,
    rods: bool = True,
    kp: float = 0.04,
    kd: float = 0.14,
) -> np.ndarray:
    """``(n, 7)`` commands from the true state: v2's PD law (attitude to zero), the rods' torque fed
    forward through the working wheels, and with ``unload_gain > 0`` the cross-product unloading
    law ``m = k (h_w x B) / |B|^2`` clipped per axis to ``m_max`` (its torque ``m x B =
    -k h_w,perp`` drains the wheels' momentum across the field)."""
    sigma, omega, wheels, field = plant.sigma, plant.omega_rad_s, plant.wheel_speed_rad_s, plant.field_b_t
    n = len(sigma)
    inertia = np.array(WHEELS.inertia_nominal_kgm2)
    h_w = wheel_momentum(wheels)
    dipole = np.zeros((n, 3))
    if rods and unload_gain > 0.0:
        b2 = np.einsum("ni,ni->n", field, field)[:, None]
        dipole = np.clip(unload_gain * cross(h_w, field) / b2, -M_MAX, M_MAX)
    demand = -inertia * (kp * sigma + kd * omega) + cross(omega, inertia * omega + h_w)
    demand = demand - cross(dipole, field)  # the wheels supply what the rods do not
    working = np.ones((n, 4), dtype=bool) if working is None else working
    u = np.empty((n, 4))
    for e in range(n):
        alloc = np.linalg.pinv((WHEELS.axes * working[e][:, None]).T)
        u[e] = -alloc @ demand[e]
    friction = friction_torque_nm(
        wheels, np.full((n, 4), WHEELS.coulomb_nm), WHEELS.viscous_nms, WHEELS.omega_linear_rad_s
    )
    out = np.empty((n, 7))
    out[:, :4] = (u - friction * working) / WHEELS.u_max_nm
    out[:, 4:] = dipole / M_MAX
    return out


def rich_faults(n: int, seed: int, bursts: int = 4) -> PlantFault:
    """Faults that exercise every branch of the fault logic within a few hundred steps: early
    onsets, reversed/scaled/dead wheels, offsets, constant friction, ramps up to 60x, bursts
    (overlapping and empty ones too), rod gains in {1, -1, 0, 0.5} (``demo.random_faults``)."""
    return random_faults(
        np.random.default_rng(seed), n, bursts=bursts, bursts_start_below=300, sort_bursts=False,
        longest_burst=60, onset_below=120,
    )  # fmt: skip
