"""``scftc-v3``'s Basilisk cross-check plan (``study/crosscheck.py`` flies it): the whole v3 plant in
orbit (wheels, rods, residual dipole, gravity gradient, solar pressure, the dipole field) on every
held-out actuator class, ``nominal`` included, and every sensor fault. The state compared is v2's
(attitude, rates, the wheel speeds as a fraction of ``Omega_max``), the checks are v2's
(``WheelGroupCheck``: saturated steps and the wheel-steps the speed limit cut, per backend).

The one-step difference restarts the reference plant (``dynamics.V3Plant``) from every recorded
Basilisk state, the inertial field held over the step included, applies the recorded command and
compares the state it reaches with Basilisk's next one: the whole map from (state, command) to the
next state, environment and rods included, checked at every step of every closed-loop run.

Over a whole flight the backends' rounding differences grow as fast as the closed loop amplifies
them, which depends on the flight: a fault-unaware ``pd`` holding a friction-faulted wheel at its
speed limit amplifies one rounding unit to a radian. Each flight is therefore also flown on its
*rounding twin*: the default backend with every state moved up by one rounding unit after every
step (``RoundingTwinPlant``). How far the twin departs from the flight is what this flight does to
one unit of rounding a step; the one-step bound lets the backends differ by ``TWIN_RATIO`` units of
a wheel at its limit a step; so each flight is held to the larger of the tolerance and
``TWIN_RATIO`` times its twin's departure. A flight that amplifies little is held to the tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Any, ClassVar

import numpy as np

from scftc_cli.evaluate import Cell
from scftc_cli.protocol import NO_PROGRESS, Progress
from scftc_cli.registry import make_controller
from scftc_cli.sim.rollout import Rollout, rollout
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.study.crosscheck import (
    GroupCheck,
    Plan,
    basilisk_backend,
    group_check,
    max_abs_diff,
    recorded,
    worst,
)
from scftc_cli.versions.v2.sim.dynamics import motor_torque_nm
from scftc_cli.versions.v2.study import WheelCrosscheckResult, WheelGroupCheck, limit_counts
from scftc_cli.versions.v3.sim.dynamics import V3Plant
from scftc_cli.versions.v3.sim.faults import AgileEpisodes
from scftc_cli.versions.v3.sim.mission import CONSTANTS, MissionFastPlant
from scftc_cli.versions.v3.spec import V3

# The teacher (true gains and rod gains: the allocation changes at the onset; offsets, friction
# and the environment stay unknown to it) rather than fdir, whose discrete decisions turn the
# backends' one-step rounding into different trajectories (as on v2); the oracle if the teacher
# cannot be built.
ADAPTIVE_PREFERENCE = ("teacher", "oracle")
# Ordered for coverage: a short check flies a reversed wheel (pd drives it into the speed limit),
# a friction fault, a dead wheel, a rod fault with a dead wheel, bursts and a ramp first; then the
# other actuator classes; then every sensor fault on top of sign faults.
GROUPS = (
    Cell("test", "sign"),
    Cell("test", "friction"),
    Cell("test", "loss"),
    Cell("test", "rod"),
    Cell("test", "intermittent"),
    Cell("test", "incipient"),
    Cell("test", "double"),
    Cell("test", "compound"),
    Cell("test", "gain_bias"),
    Cell("test", "gain"),
    Cell("test", "nominal"),
    Cell("test", "sign", "st_bias"),
    Cell("test", "sign", "st_outage"),
    Cell("test", "sign", "st_stuck"),
    Cell("test", "sign", "gyro_bias"),
    Cell("test", "sign", "mag_bias"),
    Cell("test", "sign", "mag_spike"),
)


TOLERANCE = 1e-8
"""The closed-loop tolerance on the state (sigma, omega, wheel speeds over ``Omega_max``): v2's 1e-9
held its 400-step episodes; over v3's 2400 steps a fault-unaware ``pd`` driving a friction-faulted
wheel into its speed limit ends 1.2e-9 apart on the first check flown (3 episodes: one step apart
1.1e-13, one rounding unit of a 600 rad/s wheel). Chosen after that measurement, and paired with
a bound v2 does not ask for: every one step from identical states within ``STEP_TOLERANCE``. A
flight whose rounding twin departs by more is held to ``TWIN_RATIO`` times that departure."""
STEP_TOLERANCE = 1e-12
"""The one-step tolerance (the largest of sigma, omega in rad/s and the wheel speeds in rad/s):
a few rounding units of a wheel at its 628 rad/s limit (1.1e-13 each)."""
TWIN_RATIO = STEP_TOLERANCE / float(np.spacing(CONSTANTS.wheels.omega_max_rad_s))
"""How many rounding units of a wheel at its speed limit (1.14e-13 rad/s) the one-step bound allows
the backends to differ by a step: 8.8. A flight is held to this many times its rounding twin's
departure where that exceeds the tolerance (module docstring)."""


class RoundingTwinPlant(MissionFastPlant):
    """The default backend with sigma, omega and the wheel speeds moved up by one rounding unit
    (``np.nextafter``) after every step: a flight's own response to rounding, without Basilisk."""

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        error_norm2 = super().step(k, command)
        for state in (self.sigma, self.omega_rad_s, self.wheel_speed_rad_s):  # views of the state
            np.nextafter(state, np.inf, out=state)
        return error_norm2


def flight_state_diffs(a: Rollout, b: Rollout) -> np.ndarray:
    """``(n,)`` each flight's largest state difference between two recorded runs, on v2's scale:
    sigma, omega (rad/s) and the wheel speeds over ``Omega_max`` (NaN stays NaN)."""
    omega_max = CONSTANTS.wheels.omega_max_rad_s
    parts = [
        np.abs(a.sigma - b.sigma),
        np.abs(a.omega_rad_s - b.omega_rad_s),
        np.abs(a.states["wheel_speed_rad_s"] - b.states["wheel_speed_rad_s"]) / omega_max,
    ]
    return np.max(np.concatenate([p.reshape(p.shape[0], -1) for p in parts], axis=1), axis=1)


def flight_bounds(twin_departure: np.ndarray) -> np.ndarray:
    """``(n,)`` each flight's bound on its state difference: the tolerance, or ``TWIN_RATIO``
    times its rounding twin's departure where that is larger."""
    return np.maximum(TOLERANCE, TWIN_RATIO * twin_departure)


@dataclass(frozen=True)
class MissionGroupCheck(WheelGroupCheck):
    """A ``scftc-v3`` batch: v2's checks, and per flight its state difference and its bound.

    Attributes:
        flight_state_diff: per flight, the largest state difference between the backends (v2's
            scale: sigma, omega, wheel speeds over ``Omega_max``).
        twin_departure: per flight, the same between the default backend and its rounding twin.
    """

    flight_state_diff: tuple[float, ...]
    twin_departure: tuple[float, ...]

    @property
    def flight_bound(self) -> tuple[float, ...]:
        """Per flight, the bound on its state difference (``flight_bounds``)."""
        return tuple(flight_bounds(np.array(self.twin_departure)).tolist())

    def failing_flights(self) -> list[int]:
        """The flights whose state difference is over their bound (or NaN)."""
        pairs = zip(self.flight_state_diff, self.flight_bound, strict=True)
        return [i for i, (d, b) in enumerate(pairs) if not d <= b]


@dataclass(frozen=True)
class MissionCrosscheckResult(WheelCrosscheckResult):
    """A ``scftc-v3`` cross-check: v2's state and checks over v3's 2400-step episodes, each flight
    held to the tolerance or to its rounding twin's departure times ``TWIN_RATIO``, and every one
    step to ``STEP_TOLERANCE``."""

    benchmark_version: ClassVar[str] = V3.version

    groups: list[MissionGroupCheck]  # type: ignore[assignment]
    tolerance: float = TOLERANCE
    steps: int = V3.steps

    def state_failures(self) -> list[str]:
        return [
            f"{g.controller} on {g.cell.label}, flight {i}: state difference {g.flight_state_diff[i]:.3g} "
            f"> its bound {g.flight_bound[i]:.3g}"
            for g in self.groups
            for i in g.failing_flights()
        ]

    @property
    def passed(self) -> bool:
        # ``not >`` so that a NaN difference fails the check
        return super().passed and bool(self.max_abs_step_diff <= STEP_TOLERANCE)

    def _state_diffs(self) -> dict[str, Any]:
        pairs = [pair for g in self.groups for pair in zip(g.flight_state_diff, g.flight_bound, strict=True)]
        return {
            **super()._state_diffs(),
            "max_state_diff_over_bound": worst(d / b for d, b in pairs),
            "flights_held_to_twin": sum(1 for _, b in pairs if b > TOLERANCE),
            "twin_ratio": TWIN_RATIO,
        }

    def _group_doc(self, g: GroupCheck) -> dict[str, Any]:
        assert isinstance(g, MissionGroupCheck)
        return {
            **super()._group_doc(g),
            "flight_state_diff": list(g.flight_state_diff),
            "twin_departure": list(g.twin_departure),
            "flight_bound": list(g.flight_bound),
        }


def _limits_at(plant: V3Plant, k: int, command: np.ndarray, speed: np.ndarray) -> tuple[int, int]:
    """``(episodes starting step k with a wheel at or above its speed limit, wheel-steps whose
    motor torque that limit changed)`` for the wheel commands ``(n, m)`` and start speeds
    ``(n, m)`` rad/s of step ``k``, under the faults ``plant`` holds in force then."""
    wheels = CONSTANTS.wheels
    gain, bias, _, _ = plant.faults_at(k)
    motor = motor_torque_nm(command, gain, bias, speed, wheels.u_max_nm, wheels.omega_max_rad_s)
    unlimited = motor_torque_nm(command, gain, bias, speed, wheels.u_max_nm, np.inf)
    return limit_counts(speed, motor, unlimited, wheels.omega_max_rad_s)


def speed_limits(episodes: AgileEpisodes, run: Rollout) -> tuple[int, int]:
    """``(saturated episode-steps, cut wheel-steps)`` of a recorded run (``_limits_at`` summed over
    its steps), read from its recorded speeds and commands: no plant is stepped."""
    commands = recorded(run)[0]
    speeds = run.states["wheel_speed_rad_s"]
    plant = V3Plant.of(episodes, CONSTANTS)  # only for the faults in force at each step
    m = CONSTANTS.wheels.n_wheels
    counts = [_limits_at(plant, k, commands[:, k, :m], speeds[:, k]) for k in range(commands.shape[1])]
    return sum(s for s, _ in counts), sum(c for _, c in counts)


def one_step(
    episodes: AgileEpisodes, run: Rollout, progress: Progress = NO_PROGRESS
) -> tuple[float, int, int]:
    """``(largest one-step difference, saturated episode-steps, cut wheel-steps)`` of a recorded
    Basilisk run: the reference plant restarted at every recorded state (attitude, rates, wheel
    speeds, the inertial field held over the step) with the recorded command; the difference over
    sigma, omega (rad/s) and the wheel speeds (rad/s) from the recorded next state. The counts are
    ``speed_limits``'s, taken on the way."""
    commands = recorded(run)[0]
    states = run.states
    plant = V3Plant.of(episodes, CONSTANTS)
    m = CONSTANTS.wheels.n_wheels
    diff, saturated, cut = 0.0, 0, 0
    for k in range(commands.shape[1]):
        plant.sigma = states["sigma"][:, k].copy()
        plant.omega_rad_s = states["omega_rad_s"][:, k].copy()
        plant.wheel_speed_rad_s = states["wheel_speed_rad_s"][:, k].copy()
        plant.field_n_t = states["field_n_t"][:, k].copy()
        saturated_k, cut_k = _limits_at(plant, k, commands[:, k, :m], plant.wheel_speed_rad_s)
        saturated, cut = saturated + saturated_k, cut + cut_k
        plant.step(k, commands[:, k])
        progress.advance(1)
        diff = worst(
            (
                diff,
                max_abs_diff(plant.sigma, states["sigma"][:, k + 1]),
                max_abs_diff(plant.omega_rad_s, states["omega_rad_s"][:, k + 1]),
                max_abs_diff(plant.wheel_speed_rad_s, states["wheel_speed_rad_s"][:, k + 1]),
            )
        )
    return diff, saturated, cut


def mission_check(
    spec: BenchmarkSpec,
    controller: str,
    cell: Cell,
    episodes: Any,
    ref: Rollout,
    bsk: Rollout,
    progress: Progress,
) -> MissionGroupCheck:
    """The check of one batch of ``spec``'s (v3's, or a version flying v3's mission): the Basilisk
    run's one-step replay, both backends' speed-limit counts, and the rounding twin's flight."""
    step_diff, bsk_saturated, bsk_cut = one_step(episodes, bsk, progress)
    ref_saturated, ref_cut = speed_limits(episodes, ref)
    twin = rollout(
        make_controller(controller, spec.version),
        episodes,
        record=True,
        progress=progress,
        plant=RoundingTwinPlant.of(episodes),
    )
    return MissionGroupCheck(
        **group_check(spec, controller, cell, episodes, ref, bsk),
        max_abs_step_diff=step_diff,
        max_abs_wheel_speed_diff=max_abs_diff(
            ref.states["wheel_speed_rad_s"], bsk.states["wheel_speed_rad_s"]
        ),
        saturated_steps={"numpy": ref_saturated, "basilisk": bsk_saturated},
        cut_wheel_steps={"numpy": ref_cut, "basilisk": bsk_cut},
        flight_state_diff=tuple(float(d) for d in flight_state_diffs(ref, bsk)),
        twin_departure=tuple(float(d) for d in flight_state_diffs(ref, twin)),
    )


def mission_plan(
    spec: BenchmarkSpec, groups: tuple[Cell, ...], result: type[MissionCrosscheckResult]
) -> Plan:
    """The cross-check plan of ``spec`` (v3's mission; ``groups`` its cells in dealing order):
    the teacher (else the oracle) beside ``pd``, each batch checked by ``mission_check``."""
    return Plan(
        spec,
        groups,
        ADAPTIVE_PREFERENCE,
        partial(mission_check, spec),
        result,
        basilisk_backend("scftc_cli.versions.v3.sim.basilisk"),
        check_flights=2,  # the Basilisk run's one-step replay and the rounding twin
    )


CROSSCHECK = mission_plan(V3, GROUPS, MissionCrosscheckResult)
