"""Cross-check: the same episodes through the numpy backend and Basilisk, compared state by state.

The numpy backend is what every score is computed on; it is trusted only because this check shows
it equal to Basilisk's own dynamics. Episodes mix the version's held-out actuator classes with
sensor faults, and controllers of both kinds fly them (a fault-unaware one and one of the version's
adaptive preference), so commands, sign flips, saturation and corrupted observations are all
exercised in closed loop. Every trajectory is recorded on both backends; the check passes when the
largest difference over the compared state at every step stays within the tolerance and every gate
outcome agrees.

A closed loop that spins the vehicle up (``pd`` on reversed actuators) amplifies rounding step
after step, so its free-running difference grows far above the ~1e-16 of one step.
``max_abs_step_diff`` separates the two: one step of the numpy physics from every recorded
Basilisk state, which stays at rounding level whatever the loop does.

What a version compares, and on which cells, is its ``Plan`` (``versions/<name>/study.py``, named
by its ``StudyPlan.crosscheck``): the cells, the adaptive preference, the ``GroupCheck`` of a
batch (its one-step difference and any state of its own) and its ``CrosscheckResult`` type.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from scftc_cli.errors import ScftcError, UsageError
from scftc_cli.evaluate import Cell, check_held_out_open
from scftc_cli.loading import load
from scftc_cli.protocol import NO_PROGRESS, Progress
from scftc_cli.registry import controller_spec, make_controller, registry
from scftc_cli.scoring import gate_outcomes
from scftc_cli.sim.rollout import Rollout, rollout
from scftc_cli.sim.testbed import testbed
from scftc_cli.spec import DEFAULT_BENCHMARK, BenchmarkSpec
from scftc_cli.versions import get_version

TOLERANCE = 1e-9
FAULT_UNAWARE = "pd"


def _buildable(name: str, benchmark: str = DEFAULT_BENCHMARK) -> bool:
    """Whether ``name`` is registered for ``benchmark`` and can be built (its tuned parameters exist)."""
    if name not in registry(benchmark):
        return False
    try:
        make_controller(name, benchmark)
    except ScftcError:
        return False
    return True


def default_controllers(benchmark: str = DEFAULT_BENCHMARK) -> tuple[str, ...]:
    """``pd`` plus the first buildable controller of the version's adaptive preference list; on a
    draft version the adaptive (privileged) one alone, since its held-out cells are closed to
    ``pd`` until the battery is frozen (``evaluate.check_held_out_open``)."""
    chosen = plan(benchmark)
    adaptive = next((c for c in chosen.adaptive_preference if _buildable(c, benchmark)), None)
    if get_version(benchmark).draft and adaptive is not None:
        return (adaptive,)
    return (FAULT_UNAWARE,) if adaptive is None else (FAULT_UNAWARE, adaptive)


def worst(diffs: Iterable[float]) -> float:
    """The largest difference, NaN if any is NaN (``np.max``, unlike ``max``, propagates it)."""
    diffs = list(diffs)
    return float(np.max(diffs)) if diffs else 0.0


def split_episodes(n_episodes: int, n_groups: int) -> list[int]:
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
    """Every batch of a cross-check and the verdict over all of them (a version subclasses it with
    its name and the state it compares beyond sigma and omega)."""

    benchmark_version: ClassVar[str]

    episodes: int
    controllers: tuple[str, ...]
    groups: list[GroupCheck]
    seconds: dict[str, float]
    basilisk_version: str
    tolerance: float = TOLERANCE
    steps: int = 0

    @property
    def max_abs_state_diff(self) -> float:
        """Largest ``|numpy - basilisk|`` over sigma and omega, every episode and step."""
        return worst(d for g in self.groups for d in (g.max_abs_sigma_diff, g.max_abs_omega_diff))

    @property
    def max_abs_step_diff(self) -> float:
        """Largest one-step difference from identical states (see ``one_step_diff``)."""
        return worst(g.max_abs_step_diff for g in self.groups)

    @property
    def gates_agree(self) -> bool:
        return all(v == 0 for g in self.groups for v in g.gate_disagreements.values())

    def state_failures(self) -> list[str]:
        """What in the compared state breaks the check, one line each (none: it holds): here the
        largest difference over the tolerance; a version may bound each flight differently."""
        # ``not >`` so that a NaN difference fails the check
        if self.max_abs_state_diff <= self.tolerance:
            return []
        return [f"max_abs_state_diff {self.max_abs_state_diff:.3g} > {self.tolerance:g}"]

    @property
    def passed(self) -> bool:
        return not self.state_failures() and self.gates_agree

    def _state_diffs(self) -> dict[str, Any]:
        """Summary keys after the sigma and omega differences (a version's own state)."""
        return {}

    def _coverage(self) -> dict[str, Any]:
        """Summary keys after the one-step difference (a version's own coverage counts)."""
        return {}

    def _group_doc(self, g: GroupCheck) -> dict[str, Any]:
        return {
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

    def dump(self) -> dict:
        """The JSON document ``scftc crosscheck`` prints."""
        return {
            "benchmark_version": self.benchmark_version,
            "episodes": self.episodes,
            "controllers": list(self.controllers),
            "rollouts": sum(g.n for g in self.groups),
            "steps": self.steps,
            "max_abs_state_diff": self.max_abs_state_diff,
            "max_abs_sigma_diff": worst(g.max_abs_sigma_diff for g in self.groups),
            "max_abs_omega_diff_rad_s": worst(g.max_abs_omega_diff for g in self.groups),
            **self._state_diffs(),
            "max_abs_command_diff": worst(g.max_abs_command_diff for g in self.groups),
            "max_abs_step_diff": self.max_abs_step_diff,
            **self._coverage(),
            "gates_agree": self.gates_agree,
            "tolerance": self.tolerance,
            "passed": self.passed,
            "basilisk_version": self.basilisk_version,
            "seconds": self.seconds,
            "groups": [self._group_doc(g) for g in self.groups],
        }


BACKENDS = ("numpy", "basilisk")


def max_abs_diff(a: np.ndarray, b: np.ndarray) -> float:
    """Largest absolute difference; NaN anywhere makes it NaN (and the check fail)."""
    return float(np.max(np.abs(a - b))) if a.size else 0.0


def recorded(run: Rollout) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(commands, sigma, omega)`` of a rollout flown with ``record=True``."""
    if run.commands is None or "sigma" not in run.states:
        raise ValueError("the cross-check needs recorded rollouts (record=True)")
    return run.commands, run.sigma, run.omega_rad_s


def group_check(
    spec: BenchmarkSpec, controller: str, cell: Cell, episodes: Any, ref: Rollout, bsk: Rollout
) -> dict[str, Any]:
    """The fields every version's group check shares."""
    ref_gates, bsk_gates = gate_outcomes(ref, spec.gates), gate_outcomes(bsk, spec.gates)
    return {
        "controller": controller,
        "cell": cell,
        "n": episodes.n,
        "max_abs_sigma_diff": max_abs_diff(ref.sigma, bsk.sigma),
        "max_abs_omega_diff": max_abs_diff(ref.omega_rad_s, bsk.omega_rad_s),
        "max_abs_command_diff": max_abs_diff(recorded(ref)[0], recorded(bsk)[0]),
        "gate_disagreements": {
            gate: int(np.count_nonzero(ref_gates[gate] != bsk_gates[gate])) for gate in ref_gates
        },
        "settled_k": {
            "numpy": int(np.count_nonzero(ref_gates["settled"])),
            "basilisk": int(np.count_nonzero(bsk_gates["settled"])),
        },
    }


def basilisk_backend(module: str) -> Callable[[], str]:
    """Import a version's Basilisk backend ``module`` (``BackendUnavailable`` with the install hint
    where ``bsk`` is missing); returns the function that names the installed ``bsk`` version."""

    def version() -> str:
        import importlib
        from importlib.metadata import PackageNotFoundError
        from importlib.metadata import version as installed

        importlib.import_module(module)
        try:
            return installed("bsk")
        except PackageNotFoundError:
            return "unknown"

    return version


@dataclass(frozen=True)
class Plan:
    """What the cross-check of one benchmark version flies and how it compares a batch.

    Attributes:
        spec: the version.
        groups: the cells, in the order episodes are dealt to them.
        adaptive_preference: the default adaptive controller: the first buildable one.
        check: builds a batch's ``GroupCheck`` from its episodes and both recorded rollouts,
            advancing the progress by each step it simulates itself.
        result: the ``CrosscheckResult`` type of the version.
        basilisk_version: imports the Basilisk backend and names ``bsk``'s version.
        check_flights: how many whole flights' steps ``check`` simulates a batch (v3: the
            Basilisk run's one-step replay and the rounding twin), for the progress bar's total.
    """

    spec: BenchmarkSpec
    groups: tuple[Cell, ...]
    adaptive_preference: tuple[str, ...]
    check: Callable[[str, Cell, Any, Rollout, Rollout, Progress], GroupCheck]
    result: type[CrosscheckResult]
    basilisk_version: Callable[[], str]
    check_flights: int = 0


def plan(benchmark: str = DEFAULT_BENCHMARK) -> Plan:
    """The cross-check plan of ``benchmark``; an unknown version suggests the closest one."""
    target = get_version(benchmark).study.crosscheck
    if target is None:
        raise UsageError(f"no cross-check is defined for {benchmark}")
    return load(target)


def crosscheck(
    n_episodes: int,
    controllers: Sequence[str] | None = None,
    *,
    benchmark: str = DEFAULT_BENCHMARK,
    progress: Progress = NO_PROGRESS,
) -> CrosscheckResult:
    """Fly ``n_episodes`` mixed episodes under each controller on both backends and compare.

    Args:
        n_episodes: episodes in all, spread over the version's groups (each controller flies all
            of them).
        controllers: registered names; ``default_controllers(benchmark)`` when ``None``.
        benchmark: the version whose plant and taxonomy are flown.
        progress: advanced once per simulated step of either backend and of the check's own
            flights.
    """
    if n_episodes < 1:
        raise UsageError("--episodes must be at least 1")
    chosen = plan(benchmark)
    version = chosen.spec.version
    controllers = tuple(controllers) if controllers else default_controllers(version)
    for name in controllers:  # an unknown name fails here, with a suggestion; so does a draft's held-out cell
        check_held_out_open(chosen.spec, list(chosen.groups), controller_spec(name, version).privileged)
    basilisk_version = chosen.basilisk_version()  # BackendUnavailable before any work
    bed = testbed(version)

    seconds = {"numpy": 0.0, "basilisk": 0.0}
    checks: list[GroupCheck] = []
    for cell, count in zip(chosen.groups, split_episodes(n_episodes, len(chosen.groups)), strict=True):
        if count == 0:
            continue
        # one initial condition per fault: as many distinct faults as possible
        episodes = bed.draw(cell.split, cell.fault_class, cell.sensor, n_faults=count, n_seeds=1)
        for name in controllers:
            runs = {}
            for backend in BACKENDS:
                start = time.perf_counter()
                runs[backend] = rollout(
                    make_controller(name, version), episodes, backend=backend, record=True, progress=progress
                )
                seconds[backend] += time.perf_counter() - start
            checks.append(chosen.check(name, cell, episodes, runs["numpy"], runs["basilisk"], progress))
    return chosen.result(
        episodes=n_episodes,
        controllers=controllers,
        groups=checks,
        seconds={k: round(v, 3) for k, v in seconds.items()},
        basilisk_version=basilisk_version,
        steps=chosen.spec.steps,
    )


def total_steps(n_episodes: int, controllers: Sequence[str], benchmark: str = DEFAULT_BENCHMARK) -> int:
    """Steps a cross-check simulates, both backends and the checks together (for a progress bar)."""
    chosen = plan(benchmark)
    batches = sum(1 for c in split_episodes(n_episodes, len(chosen.groups)) if c > 0) * len(controllers)
    return (len(BACKENDS) + chosen.check_flights) * batches * chosen.spec.steps
