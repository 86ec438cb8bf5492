"""Shared batches and a tiny feedback law for the v2 plant tests."""

from __future__ import annotations

import numpy as np

from scftc_cli.sim.mrp import cross
from scftc_cli.versions.v2.sim.dynamics import RPM_TO_RAD_S, WheelConstants, friction_torque_nm
from scftc_cli.versions.v2.spec import V2, ReactionWheelPlant

assert isinstance(V2.plant, ReactionWheelPlant)
CONSTANTS = WheelConstants.of(V2.plant)


def healthy(n: int, seed: int, constants: WheelConstants = CONSTANTS) -> dict[str, np.ndarray]:
    """Constructor arguments for ``n`` healthy episodes with scftc-v2's initial conditions:
    ``sigma0`` per axis in [-0.5, 0.5], ``w0`` in [-0.02, 0.02] rad/s, wheels in [-1000, 1000]
    rpm, inertia scale in [0.7, 2.3]."""
    rng = np.random.default_rng(seed)
    m = constants.n_wheels
    return {
        "sigma0": rng.uniform(-0.5, 0.5, (n, 3)),
        "omega0_rad_s": rng.uniform(-0.02, 0.02, (n, 3)),
        "wheel_speed0_rad_s": rng.uniform(-1000.0, 1000.0, (n, m)) * RPM_TO_RAD_S,
        "inertia_scale": rng.uniform(0.7, 2.3, n),
        "gain": np.ones((n, m)),
        "bias": np.zeros((n, m)),
        "coulomb_nm": np.full((n, m), constants.coulomb_nm),
        "onset_step": np.zeros(n, dtype=np.int64),
    }


def faulted(n: int, seed: int, constants: WheelConstants = CONSTANTS) -> dict[str, np.ndarray]:
    """``healthy`` plus every kind of actuator fault at random onsets: reversed and scaled gains,
    offsets, a wheel with up to 60x friction, and a dead wheel in every fifth episode."""
    args = healthy(n, seed, constants)
    rng = np.random.default_rng(seed + 1)
    m = constants.n_wheels
    sign = np.where(rng.random((n, m)) < 0.2, -1.0, 1.0)
    args["gain"] = sign * rng.uniform(0.3, 2.0, (n, m))
    args["gain"][::5, 2] = 0.0
    args["bias"] = rng.uniform(-0.3, 0.3, (n, m))
    args["coulomb_nm"][np.arange(n), rng.integers(0, m, n)] *= rng.uniform(1.0, 60.0, n)
    args["onset_step"] = rng.integers(0, 121, n)
    return args


def pd_command(
    sigma: np.ndarray,
    omega_rad_s: np.ndarray,
    wheel_speed_rad_s: np.ndarray,
    working: np.ndarray | None = None,
    constants: WheelConstants = CONSTANTS,
) -> np.ndarray:
    """scftc-v2's analytic law on the true state: ``L = -I0 (Kp s + Kd w) + w x (I0 w + sum_i Js
    Omega_i g_i)`` allocated through the pseudo-inverse of the working wheels' axes (a wheel
    torque ``u`` puts ``-u g`` on the hub), plus the nominal friction feed-forward; returns the
    normalized commands ``(n, m)`` (unclipped: the plant clips)."""
    axes, js, u_max = constants.axes, constants.js_kgm2, constants.u_max_nm
    inertia = np.array(constants.inertia_nominal_kgm2)
    momentum = inertia * omega_rad_s + (js * wheel_speed_rad_s) @ axes
    demand = -inertia * (0.04 * sigma + 0.14 * omega_rad_s) + cross(omega_rad_s, momentum)
    n, m = wheel_speed_rad_s.shape
    working = np.ones((n, m), dtype=bool) if working is None else working
    u = np.empty((n, m))
    for e in range(n):  # a handful of episodes: clarity over speed
        alloc = np.linalg.pinv((axes * working[e][:, None]).T)  # (m, 3), zero rows for dead wheels
        u[e] = -alloc @ demand[e]
    coulomb = np.full((n, m), constants.coulomb_nm)
    friction = friction_torque_nm(
        wheel_speed_rad_s, coulomb, constants.viscous_nms, constants.omega_linear_rad_s
    )
    return (u - friction * working) / u_max
