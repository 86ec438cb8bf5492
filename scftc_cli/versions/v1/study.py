"""``scftc-v1``'s Basilisk cross-check plan (``study/crosscheck.py`` flies it): the held-out
actuator classes and two sensor faults, ``pd`` and the first buildable adaptive law, compared on
sigma and omega, with the one-step difference of the reference RK4 from every Basilisk state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from scftc_cli.evaluate import Cell
from scftc_cli.protocol import Progress
from scftc_cli.sim.rollout import Rollout
from scftc_cli.study.crosscheck import (
    CrosscheckResult,
    GroupCheck,
    Plan,
    basilisk_backend,
    group_check,
    max_abs_diff,
    recorded,
    worst,
)
from scftc_cli.versions.v1.sim.dynamics import rk4_step
from scftc_cli.versions.v1.sim.faults import RigidEpisodes
from scftc_cli.versions.v1.spec import V1

# The first one that can be built wins; the privileged oracles are the fallback while no adaptive
# law (or none of its tuned parameters) is there.
ADAPTIVE_PREFERENCE = ("rls_dob", "classical_adaptive", "icl_adaptive", "nussbaum", "bias_oracle", "teacher")
# Held-out actuator classes, then sensor faults on top of sign faults.
GROUPS = (
    Cell("test", "sign"),
    Cell("test", "gain"),
    Cell("test", "gain_bias"),
    Cell("test", "loss"),
    Cell("test", "sign", "bias_0.2"),
    Cell("test", "sign", "stuck"),
)


@dataclass(frozen=True)
class RigidCrosscheckResult(CrosscheckResult):
    """A ``scftc-v1`` cross-check: sigma and omega compared."""

    benchmark_version: ClassVar[str] = V1.version
    steps: int = V1.steps


def one_step_diff(episodes: RigidEpisodes, run: Rollout) -> float:
    """Largest ``|numpy step - basilisk step|`` from the very same state and torque.

    The free-running difference of a closed loop that spins up (``pd`` on reversed axes) grows
    with the loop's own instability: rounding at 1e-16 is amplified step after step. Restarting
    the numpy step from each recorded Basilisk state isolates the question of whether the two
    backends are the same map, whatever the loop does.
    """
    commands, sigma_run, omega_run = recorded(run)
    n, steps = commands.shape[:2]
    tau_max = V1.plant.tau_max_nm
    torque = (commands * episodes.fault.gain[:, None] + episodes.fault.bias[:, None]) * tau_max
    inertia = np.repeat(
        episodes.fault.inertia_scale[:, None] * np.array(V1.plant.inertia_nominal_kgm2), steps, axis=0
    )
    flat = lambda x: x.reshape(n * steps, 3)  # noqa: E731
    sigma, omega = rk4_step(flat(sigma_run[:, :-1]), flat(omega_run[:, :-1]), flat(torque), inertia, V1.dt_s)
    return worst((max_abs_diff(sigma, flat(sigma_run[:, 1:])), max_abs_diff(omega, flat(omega_run[:, 1:]))))


def _rigid_check(
    controller: str, cell: Cell, episodes: Any, ref: Rollout, bsk: Rollout, _progress: Progress
) -> GroupCheck:
    return GroupCheck(
        **group_check(V1, controller, cell, episodes, ref, bsk),
        max_abs_step_diff=one_step_diff(episodes, bsk),
    )


CROSSCHECK = Plan(
    V1,
    GROUPS,
    ADAPTIVE_PREFERENCE,
    _rigid_check,
    RigidCrosscheckResult,
    basilisk_backend("scftc_cli.versions.v1.sim.basilisk"),
)
