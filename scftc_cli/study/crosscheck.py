"""Cross-check: the same episodes through the numpy backend and Basilisk, compared state by state.

The numpy backend is what every score is computed on; it is trusted only because this check shows
it equal to Basilisk's own ``spacecraft`` hub. Episodes mix every actuator class of the held-out
split with sensor faults, and controllers of both kinds fly them (a fault-unaware one and an
adaptive one), so commands, sign flips, saturation and corrupted observations are all exercised
in closed loop. Every trajectory is recorded on both backends; the check passes when the largest
difference over sigma and omega at every step stays within the tolerance and every gate outcome
agrees.

A closed loop that spins the vehicle up (``pd`` on reversed axes reaches ~10 rad/s) amplifies
rounding step after step, so its free-running difference grows far above the ~1e-16 of one step
(~1e-11 over the 20 default episodes, up to ~1e-7 on some of a larger draw). ``max_abs_step_diff``
separates the two: one step of the numpy physics from every recorded Basilisk state, which stays
at rounding level whatever the loop does.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from scftc_cli.errors import ScftcError, UsageError
from scftc_cli.evaluate import Cell
from scftc_cli.protocol import NO_PROGRESS, Progress
from scftc_cli.registry import controller_spec, make_controller, registry
from scftc_cli.scoring import gate_outcomes
from scftc_cli.sim.rollout import Rollout, rollout
from scftc_cli.sim.v1 import TESTBED
from scftc_cli.sim.v1.dynamics import rk4_step
from scftc_cli.sim.v1.faults import RigidEpisodes
from scftc_cli.spec import V1

TOLERANCE = 1e-9
FAULT_UNAWARE = "pd"
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


def _buildable(name: str) -> bool:
    """Whether ``name`` is registered and can be built (its tuned parameters exist)."""
    if name not in registry(V1.version):
        return False
    try:
        make_controller(name)
    except ScftcError:
        return False
    return True


def default_controllers() -> tuple[str, ...]:
    """``pd`` plus the first buildable controller of ``ADAPTIVE_PREFERENCE``."""
    adaptive = next((c for c in ADAPTIVE_PREFERENCE if _buildable(c)), None)
    return (FAULT_UNAWARE,) if adaptive is None else (FAULT_UNAWARE, adaptive)


def _worst(diffs: Iterable[float]) -> float:
    """The largest difference, NaN if any is NaN (``np.max``, unlike ``max``, propagates it)."""
    diffs = list(diffs)
    return float(np.max(diffs)) if diffs else 0.0


def split_episodes(n_episodes: int, n_groups: int = len(GROUPS)) -> list[int]:
    """How many of ``n_episodes`` each group gets: as even as possible, earlier groups first."""
    base, extra = divmod(n_episodes, n_groups)
    return [base + (g < extra) for g in range(n_groups)]


@dataclass(frozen=True)
class GroupCheck:
    """One (controller, cell) batch flown on both backends."""

    controller: str
    cell: Cell
    n: int
    max_abs_sigma_diff: float
    max_abs_omega_diff: float
    max_abs_command_diff: float
    max_abs_step_diff: float
    gate_disagreements: dict[str, int]
    settled_k: dict[str, int]


@dataclass(frozen=True)
class CrosscheckResult:
    """Every batch of a cross-check and the verdict over all of them."""

    episodes: int
    controllers: tuple[str, ...]
    groups: list[GroupCheck]
    seconds: dict[str, float]
    basilisk_version: str
    tolerance: float = TOLERANCE
    steps: int = field(default=V1.steps)

    @property
    def max_abs_state_diff(self) -> float:
        """Largest ``|numpy - basilisk|`` over sigma and omega, every episode and step."""
        return _worst(d for g in self.groups for d in (g.max_abs_sigma_diff, g.max_abs_omega_diff))

    @property
    def max_abs_step_diff(self) -> float:
        """Largest one-step difference from identical states (see ``one_step_diff``)."""
        return _worst(g.max_abs_step_diff for g in self.groups)

    @property
    def gates_agree(self) -> bool:
        return all(v == 0 for g in self.groups for v in g.gate_disagreements.values())

    @property
    def passed(self) -> bool:
        # ``not >`` so that a NaN difference fails the check
        return bool(self.max_abs_state_diff <= self.tolerance) and self.gates_agree

    def dump(self) -> dict:
        """The JSON document ``scftc crosscheck`` prints."""
        return {
            "benchmark_version": V1.version,
            "episodes": self.episodes,
            "controllers": list(self.controllers),
            "rollouts": sum(g.n for g in self.groups),
            "steps": self.steps,
            "max_abs_state_diff": self.max_abs_state_diff,
            "max_abs_sigma_diff": _worst(g.max_abs_sigma_diff for g in self.groups),
            "max_abs_omega_diff_rad_s": _worst(g.max_abs_omega_diff for g in self.groups),
            "max_abs_command_diff": _worst(g.max_abs_command_diff for g in self.groups),
            "max_abs_step_diff": self.max_abs_step_diff,
            "gates_agree": self.gates_agree,
            "tolerance": self.tolerance,
            "passed": self.passed,
            "basilisk_version": self.basilisk_version,
            "seconds": self.seconds,
            "groups": [
                {
                    "controller": g.controller,
                    "split": g.cell.split,
                    "class": g.cell.fault_class,
                    "sensor": g.cell.sensor,
                    "n": g.n,
                    "max_abs_sigma_diff": g.max_abs_sigma_diff,
                    "max_abs_omega_diff_rad_s": g.max_abs_omega_diff,
                    "max_abs_command_diff": g.max_abs_command_diff,
                    "max_abs_step_diff": g.max_abs_step_diff,
                    "gate_disagreements": g.gate_disagreements,
                    "settled_k": g.settled_k,
                }
                for g in self.groups
            ],
        }


def _max_abs_diff(a: np.ndarray, b: np.ndarray) -> float:
    """Largest absolute difference; NaN anywhere makes it NaN (and the check fail)."""
    return float(np.max(np.abs(a - b))) if a.size else 0.0


def recorded(run: Rollout) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(commands, sigma, omega)`` of a rollout flown with ``record=True``."""
    if run.commands is None or "sigma" not in run.states:
        raise ValueError("the cross-check needs recorded rollouts (record=True)")
    return run.commands, run.sigma, run.omega_rad_s


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
    return _worst(
        (_max_abs_diff(sigma, flat(sigma_run[:, 1:])), _max_abs_diff(omega, flat(omega_run[:, 1:])))
    )


def crosscheck(
    n_episodes: int,
    controllers: Sequence[str] | None = None,
    *,
    progress: Progress = NO_PROGRESS,
) -> CrosscheckResult:
    """Fly ``n_episodes`` mixed episodes under each controller on both backends and compare.

    Args:
        n_episodes: episodes in all, spread over ``GROUPS`` (each controller flies all of them).
        controllers: registered names; ``default_controllers()`` when ``None``.
        progress: advanced once per simulated step of either backend.
    """
    if n_episodes < 1:
        raise UsageError("--episodes must be at least 1")
    controllers = tuple(controllers) if controllers else default_controllers()
    for name in controllers:
        controller_spec(name, V1.version)  # an unknown name fails here, with a suggestion
    from scftc_cli.sim.v1.basilisk import basilisk_version  # BackendUnavailable before any work

    seconds = {"numpy": 0.0, "basilisk": 0.0}
    checks: list[GroupCheck] = []
    for cell, count in zip(GROUPS, split_episodes(n_episodes), strict=True):
        if count == 0:
            continue
        # one initial condition per fault: as many distinct faults as possible
        episodes = TESTBED.draw(cell.split, cell.fault_class, cell.sensor, n_faults=count, n_seeds=1)
        for name in controllers:
            runs = {}
            for backend in ("numpy", "basilisk"):
                start = time.perf_counter()
                runs[backend] = rollout(
                    make_controller(name), episodes, backend=backend, record=True, progress=progress
                )
                seconds[backend] += time.perf_counter() - start
            ref, bsk = runs["numpy"], runs["basilisk"]
            ref_gates, bsk_gates = gate_outcomes(ref, V1.gates), gate_outcomes(bsk, V1.gates)
            checks.append(
                GroupCheck(
                    controller=name,
                    cell=cell,
                    n=episodes.n,
                    max_abs_sigma_diff=_max_abs_diff(ref.sigma, bsk.sigma),
                    max_abs_omega_diff=_max_abs_diff(ref.omega_rad_s, bsk.omega_rad_s),
                    max_abs_command_diff=_max_abs_diff(recorded(ref)[0], recorded(bsk)[0]),
                    max_abs_step_diff=one_step_diff(episodes, bsk),
                    gate_disagreements={
                        gate: int(np.count_nonzero(ref_gates[gate] != bsk_gates[gate])) for gate in ref_gates
                    },
                    settled_k={
                        "numpy": int(np.count_nonzero(ref_gates["settled"])),
                        "basilisk": int(np.count_nonzero(bsk_gates["settled"])),
                    },
                )
            )
    return CrosscheckResult(
        episodes=n_episodes,
        controllers=controllers,
        groups=checks,
        seconds={k: round(v, 3) for k, v in seconds.items()},
        basilisk_version=basilisk_version(),
    )


def total_steps(n_episodes: int, controllers: Sequence[str]) -> int:
    """Steps a cross-check simulates, both backends together (for a progress bar)."""
    batches = sum(1 for c in split_episodes(n_episodes) if c > 0) * len(controllers)
    return 2 * batches * V1.steps
