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

``scftc-v2`` (``--benchmark scftc-v2``) flies the reaction-wheel plant the same way, on its held-out
actuator classes (a friction fault and a dead wheel among them) and every sensor fault. The state
compared also holds the wheel speeds, held to the tolerance as a fraction of ``Omega_max`` (their
rad/s difference is reported too: a spinning-up ``pd`` loop grows one rounding unit of a 600 rad/s
wheel, 1.1e-13, to ~1e-9 rad/s over 400 steps, ~2e-12 of ``Omega_max``). Each group counts the
steps that start with a wheel at or above ``Omega_max`` and the wheel-steps whose motor torque the
speed limit cut: ``pd`` drives a reversed wheel into the limit, so the speed cut is exercised in
every ``pd`` group. The one-step difference recomputes the motor torque from the recorded command
and the recorded Basilisk wheel speeds (``v2.dynamics.motor_torque_nm``), so it checks the whole
map from (state, command) to the next state, speed cut included.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from scftc_cli.errors import ScftcError, UsageError
from scftc_cli.evaluate import Cell
from scftc_cli.protocol import NO_PROGRESS, Progress
from scftc_cli.registry import controller_spec, make_controller, registry
from scftc_cli.scoring import gate_outcomes
from scftc_cli.sim.rollout import Rollout, rollout
from scftc_cli.sim.testbed import testbed
from scftc_cli.sim.v1.dynamics import rk4_step
from scftc_cli.sim.v1.faults import RigidEpisodes
from scftc_cli.spec import DEFAULT_BENCHMARK, V1, V2, BenchmarkSpec, get_spec

if TYPE_CHECKING:
    from scftc_cli.sim.v2.faults import WheelEpisodes

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
# scftc-v2: the teacher (gain known, offsets and friction not: the allocation changes at the onset,
# the friction fault stays unknown). Not the v2 adaptive laws: their discrete decisions (nussbaum's
# sign switching, fdir's change tests) turn the backends' 1e-13 one-step difference into different
# trajectories (measured on the default 20 episodes: 1.7 rad with nussbaum, 2e-3 with fdir), which
# says nothing about the plants; the one-step difference is reported beside every closed-loop run.
V2_ADAPTIVE_PREFERENCE = ("teacher", "bias_oracle")
# Ordered for coverage: a short check (3 episodes) still flies a reversed wheel (which ``pd``
# drives into the speed limit), a friction fault and a dead wheel; then the other actuator
# classes, then every sensor fault on top of sign faults.
V2_GROUPS = (
    Cell("test", "sign"),
    Cell("test", "friction"),
    Cell("test", "loss"),
    Cell("test", "gain_bias"),
    Cell("test", "gain"),
    Cell("test", "sign", "st_bias"),
    Cell("test", "sign", "st_outage"),
    Cell("test", "sign", "st_stuck"),
    Cell("test", "sign", "gyro_bias"),
)


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
    """``pd`` plus the first buildable controller of the version's adaptive preference list."""
    chosen = plan(benchmark)
    adaptive = next((c for c in chosen.adaptive_preference if _buildable(c, benchmark)), None)
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
class WheelGroupCheck(GroupCheck):
    """A ``scftc-v2`` batch: also the wheel speeds, and how often the speed limit acted.

    Attributes:
        max_abs_wheel_speed_diff: largest ``|numpy - basilisk|`` wheel speed, rad/s.
        saturated_steps: per backend, episode-steps that began with a wheel at or above
            ``Omega_max`` (``|Omega| >= Omega_max``).
        cut_wheel_steps: per backend, wheel-steps whose motor torque the speed limit set to zero
            (the command would have spun a wheel at the limit further up).
    """

    max_abs_wheel_speed_diff: float
    saturated_steps: dict[str, int]
    cut_wheel_steps: dict[str, int]


@dataclass(frozen=True)
class CrosscheckResult:
    """Every batch of a cross-check and the verdict over all of them."""

    benchmark_version: ClassVar[str] = V1.version

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

    def _state_diffs(self) -> dict[str, Any]:
        """Summary keys after the sigma and omega differences (none for ``scftc-v1``)."""
        return {}

    def _coverage(self) -> dict[str, Any]:
        """Summary keys after the one-step difference (none for ``scftc-v1``)."""
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
            "max_abs_sigma_diff": _worst(g.max_abs_sigma_diff for g in self.groups),
            "max_abs_omega_diff_rad_s": _worst(g.max_abs_omega_diff for g in self.groups),
            **self._state_diffs(),
            "max_abs_command_diff": _worst(g.max_abs_command_diff for g in self.groups),
            "max_abs_step_diff": self.max_abs_step_diff,
            **self._coverage(),
            "gates_agree": self.gates_agree,
            "tolerance": self.tolerance,
            "passed": self.passed,
            "basilisk_version": self.basilisk_version,
            "seconds": self.seconds,
            "groups": [self._group_doc(g) for g in self.groups],
        }


@dataclass(frozen=True)
class WheelCrosscheckResult(CrosscheckResult):
    """A ``scftc-v2`` cross-check: the state compared holds the wheel speeds too."""

    benchmark_version: ClassVar[str] = V2.version

    groups: list[WheelGroupCheck]  # type: ignore[assignment]
    steps: int = field(default=V2.steps)

    @property
    def max_abs_state_diff(self) -> float:
        """Largest ``|numpy - basilisk|`` over sigma, omega (rad/s) and the wheel speeds as a
        fraction of ``Omega_max``, each on the scale of its own range.

        The wheel speeds run up to ``Omega_max`` ~ 628 rad/s, where one rounding unit is 1.1e-13
        rad/s: in rad/s the tolerance would ask ~600 times more of them than of sigma or omega.
        Their difference in rad/s is reported too (``max_abs_wheel_speed_diff_rad_s``).
        """
        omega_max = _omega_max_rad_s()
        return _worst(
            d
            for g in self.groups
            for d in (g.max_abs_sigma_diff, g.max_abs_omega_diff, g.max_abs_wheel_speed_diff / omega_max)
        )

    def _state_diffs(self) -> dict[str, Any]:
        wheels = _worst(g.max_abs_wheel_speed_diff for g in self.groups)
        return {
            "max_abs_wheel_speed_diff_rad_s": wheels,
            "max_abs_wheel_speed_diff_over_omega_max": wheels / _omega_max_rad_s(),
        }

    def _coverage(self) -> dict[str, Any]:
        return {
            "saturated_steps": {b: sum(g.saturated_steps[b] for g in self.groups) for b in BACKENDS},
            "cut_wheel_steps": {b: sum(g.cut_wheel_steps[b] for g in self.groups) for b in BACKENDS},
        }

    def _group_doc(self, g: GroupCheck) -> dict[str, Any]:
        assert isinstance(g, WheelGroupCheck)
        doc = super()._group_doc(g)
        return {
            **{k: v for k, v in doc.items() if k not in ("gate_disagreements", "settled_k")},
            "max_abs_wheel_speed_diff_rad_s": g.max_abs_wheel_speed_diff,
            "saturated_steps": g.saturated_steps,
            "cut_wheel_steps": g.cut_wheel_steps,
            "gate_disagreements": g.gate_disagreements,
            "settled_k": g.settled_k,
        }


BACKENDS = ("numpy", "basilisk")


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


def _omega_max_rad_s() -> float:
    from scftc_cli.sim.v2 import CONSTANTS

    return CONSTANTS.omega_max_rad_s


def wheel_torques(episodes: WheelEpisodes, run: Rollout) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(motor, unlimited, coulomb)`` ``(n, steps, m)`` N m over every recorded step of a v2 run.

    ``motor`` is what the plant's motor map (``v2.dynamics.motor_torque_nm``: fault in force,
    clip, speed limit) makes of the recorded command at the recorded wheel speeds; ``unlimited``
    the same without the speed limit (where they differ, the limit cut the torque); ``coulomb``
    each wheel's Coulomb friction in force (the fault's from the onset on).
    """
    from scftc_cli.sim.v2 import CONSTANTS as c
    from scftc_cli.sim.v2.dynamics import motor_torque_nm

    commands = recorded(run)[0]
    fault, steps = episodes.fault, commands.shape[1]
    active = (np.arange(steps)[None, :] >= fault.onset_step[:, None])[:, :, None]  # (n, steps, 1)
    gain = np.where(active, fault.gain[:, None], 1.0)
    bias = np.where(active, fault.bias[:, None], 0.0)
    coulomb = np.where(active, (fault.friction_multiplier * c.coulomb_nm)[:, None], c.coulomb_nm)
    speed = run.states["wheel_speed_rad_s"][:, :-1]  # at the start of each step
    motor = motor_torque_nm(commands, gain, bias, speed, c.u_max_nm, c.omega_max_rad_s)
    unlimited = motor_torque_nm(commands, gain, bias, speed, c.u_max_nm, np.inf)
    return motor, unlimited, coulomb


def wheel_one_step_diff(episodes: WheelEpisodes, run: Rollout) -> float:
    """``one_step_diff`` for ``scftc-v2``: one reference RK4 step (``v2.dynamics.rk4_step``) from
    every recorded state, with the motor torque of ``wheel_torques``; the largest difference from
    the recorded next state over sigma, omega (rad/s) and the wheel speeds (rad/s)."""
    from scftc_cli.sim.v2 import CONSTANTS as c
    from scftc_cli.sim.v2.dynamics import MassProperties
    from scftc_cli.sim.v2.dynamics import rk4_step as wheel_rk4_step

    motor, _, coulomb = wheel_torques(episodes, run)
    n, steps, m = motor.shape
    mass = MassProperties.of(c, np.repeat(episodes.fault.inertia_scale, steps))
    before = {name: x[:, :-1].reshape(n * steps, -1) for name, x in run.states.items()}
    after = {name: x[:, 1:].reshape(n * steps, -1) for name, x in run.states.items()}
    stepped = wheel_rk4_step(
        before["sigma"],
        before["omega_rad_s"],
        before["wheel_speed_rad_s"],
        motor.reshape(n * steps, m),
        coulomb.reshape(n * steps, m),
        mass,
        c,
    )
    names = ("sigma", "omega_rad_s", "wheel_speed_rad_s")
    return _worst(_max_abs_diff(x, after[name]) for name, x in zip(names, stepped, strict=True))


def saturation(episodes: WheelEpisodes, run: Rollout) -> tuple[int, int]:
    """``(saturated episode-steps, cut wheel-steps)`` of a recorded v2 run (see ``WheelGroupCheck``)."""
    speed = run.states["wheel_speed_rad_s"][:, :-1]
    motor, unlimited, _ = wheel_torques(episodes, run)
    saturated = np.any(np.abs(speed) >= _omega_max_rad_s(), axis=2)
    return int(np.count_nonzero(saturated)), int(np.count_nonzero(motor != unlimited))


def _group_check(
    spec: BenchmarkSpec, controller: str, cell: Cell, episodes: Any, ref: Rollout, bsk: Rollout
) -> dict[str, Any]:
    """The fields every version's group check shares."""
    ref_gates, bsk_gates = gate_outcomes(ref, spec.gates), gate_outcomes(bsk, spec.gates)
    return {
        "controller": controller,
        "cell": cell,
        "n": episodes.n,
        "max_abs_sigma_diff": _max_abs_diff(ref.sigma, bsk.sigma),
        "max_abs_omega_diff": _max_abs_diff(ref.omega_rad_s, bsk.omega_rad_s),
        "max_abs_command_diff": _max_abs_diff(recorded(ref)[0], recorded(bsk)[0]),
        "gate_disagreements": {
            gate: int(np.count_nonzero(ref_gates[gate] != bsk_gates[gate])) for gate in ref_gates
        },
        "settled_k": {
            "numpy": int(np.count_nonzero(ref_gates["settled"])),
            "basilisk": int(np.count_nonzero(bsk_gates["settled"])),
        },
    }


def _rigid_check(controller: str, cell: Cell, episodes: Any, ref: Rollout, bsk: Rollout) -> GroupCheck:
    return GroupCheck(
        **_group_check(V1, controller, cell, episodes, ref, bsk),
        max_abs_step_diff=one_step_diff(episodes, bsk),
    )


def _wheel_check(controller: str, cell: Cell, episodes: Any, ref: Rollout, bsk: Rollout) -> WheelGroupCheck:
    counts = {"numpy": saturation(episodes, ref), "basilisk": saturation(episodes, bsk)}
    return WheelGroupCheck(
        **_group_check(V2, controller, cell, episodes, ref, bsk),
        max_abs_step_diff=wheel_one_step_diff(episodes, bsk),
        max_abs_wheel_speed_diff=_max_abs_diff(
            ref.states["wheel_speed_rad_s"], bsk.states["wheel_speed_rad_s"]
        ),
        saturated_steps={b: counts[b][0] for b in BACKENDS},
        cut_wheel_steps={b: counts[b][1] for b in BACKENDS},
    )


def _basilisk_backend(module: str) -> Callable[[], str]:
    """Import the version's Basilisk backend (``BackendUnavailable`` with the install hint where
    ``bsk`` is missing); returns the function that names the installed ``bsk`` version."""

    def version() -> str:
        import importlib

        importlib.import_module(module)
        from scftc_cli.sim.v1.basilisk import basilisk_version

        return basilisk_version()

    return version


@dataclass(frozen=True)
class Plan:
    """What the cross-check of one benchmark version flies and how it compares a batch.

    Attributes:
        spec: the version.
        groups: the cells, in the order episodes are dealt to them.
        adaptive_preference: the default adaptive controller: the first buildable one.
        check: builds a batch's ``GroupCheck`` from its episodes and both recorded rollouts.
        result: the ``CrosscheckResult`` type of the version.
        basilisk_version: imports the Basilisk backend and names ``bsk``'s version.
    """

    spec: BenchmarkSpec
    groups: tuple[Cell, ...]
    adaptive_preference: tuple[str, ...]
    check: Callable[[str, Cell, Any, Rollout, Rollout], GroupCheck]
    result: type[CrosscheckResult]
    basilisk_version: Callable[[], str]


PLANS: dict[str, Plan] = {
    V1.version: Plan(
        V1,
        GROUPS,
        ADAPTIVE_PREFERENCE,
        _rigid_check,
        CrosscheckResult,
        _basilisk_backend("scftc_cli.sim.v1.basilisk"),
    ),
    V2.version: Plan(
        V2,
        V2_GROUPS,
        V2_ADAPTIVE_PREFERENCE,
        _wheel_check,
        WheelCrosscheckResult,
        _basilisk_backend("scftc_cli.sim.v2.basilisk"),
    ),
}


def plan(benchmark: str = DEFAULT_BENCHMARK) -> Plan:
    """The cross-check plan of ``benchmark``; an unknown version suggests the closest one."""
    get_spec(benchmark)
    if benchmark not in PLANS:
        raise UsageError(f"no cross-check is defined for {benchmark}")
    return PLANS[benchmark]


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
        progress: advanced once per simulated step of either backend.
    """
    if n_episodes < 1:
        raise UsageError("--episodes must be at least 1")
    chosen = plan(benchmark)
    version = chosen.spec.version
    controllers = tuple(controllers) if controllers else default_controllers(version)
    for name in controllers:
        controller_spec(name, version)  # an unknown name fails here, with a suggestion
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
            checks.append(chosen.check(name, cell, episodes, runs["numpy"], runs["basilisk"]))
    return chosen.result(
        episodes=n_episodes,
        controllers=controllers,
        groups=checks,
        seconds={k: round(v, 3) for k, v in seconds.items()},
        basilisk_version=basilisk_version,
    )


def total_steps(n_episodes: int, controllers: Sequence[str], benchmark: str = DEFAULT_BENCHMARK) -> int:
    """Steps a cross-check simulates, both backends together (for a progress bar)."""
    chosen = plan(benchmark)
    batches = sum(1 for c in split_episodes(n_episodes, len(chosen.groups)) if c > 0) * len(controllers)
    return 2 * batches * chosen.spec.steps
