"""The protocols every layer shares, and nothing heavy: controllers, their context, progress.

A controller is batch-first: ``reset(n, context)`` once per batch of episodes, then
``act(obs (n, obs_dim)) -> commands (n, action_dim)`` once per control step. It sees only
observations and the public constants of its benchmark version (``Context``); only a controller
marked ``privileged`` (an oracle, an upper bound) is handed the true fault in its context.

This module imports numpy alone, so the simulator, scoring and the submission sandbox's child can
import it without pulling in the battery, torch or the command line.
"""

from __future__ import annotations

import typing
from abc import ABC, abstractmethod
from dataclasses import dataclass, fields, is_dataclass
from typing import Any, ClassVar

import numpy as np


@dataclass(frozen=True)
class TrueFault:
    """A body-torque plant's identifiable fault per episode: ``theta = g/f``, ``beta = b/f``, ``(n, 3)``
    (what a privileged oracle of such a plant is handed)."""

    theta: np.ndarray
    beta: np.ndarray


@dataclass(frozen=True)
class WheelKnowledge:
    """What a controller knows about its reaction wheels (public constants).

    Attributes:
        spin_axes: ``(m, 3)`` unit spin axes ``g_i``, body frame.
        u_max_nm: motor torque per wheel at command 1.
        omega_max_rad_s: speed above which a spin-up torque is cut.
        spin_inertia_kgm2, transverse_inertia_kgm2: ``Js``, ``Jt`` of each wheel.
        coulomb_nm, viscous_nms, omega_linear_rad_s: nominal bearing friction ``fC0``, ``cV``, ``wLC``.
    """

    spin_axes: np.ndarray
    u_max_nm: float
    omega_max_rad_s: float
    spin_inertia_kgm2: float
    transverse_inertia_kgm2: float
    coulomb_nm: float
    viscous_nms: float
    omega_linear_rad_s: float


@dataclass(frozen=True)
class SensorKnowledge:
    """The noise figures of redundant noisy sensors, per sample, in SI units (never their draws).

    Attributes:
        star_tracker_heads: number of heads.
        star_tracker_noise_rad: 1-sigma rotation noise per axis of a head.
        gyro_noise_rad_s: 1-sigma white rate noise per sample (``ARW / sqrt(dt)``).
        gyro_bias_bound_rad_s: the constant gyro bias is uniform in +- this per axis.
        tachometer_noise_rad_s: 1-sigma wheel-speed noise.
    """

    star_tracker_heads: int
    star_tracker_noise_rad: float
    gyro_noise_rad_s: float
    gyro_bias_bound_rad_s: float
    tachometer_noise_rad_s: float
    magnetometer_noise_t: float | None = None


@dataclass(frozen=True)
class RodKnowledge:
    """What a controller knows about its magnetorquer rods (public constants).

    Attributes:
        axes: ``(r, 3)`` unit dipole axes, body frame.
        dipole_max_am2: each rod's dipole at command 1.
        residual_dipole_nominal_am2: ``(3,)`` the spacecraft's nominal residual dipole, body frame.
    """

    axes: np.ndarray
    dipole_max_am2: float
    residual_dipole_nominal_am2: np.ndarray


@dataclass(frozen=True)
class OrbitKnowledge:
    """What a controller knows about each episode's orbit (circular).

    Attributes:
        altitude_m: ``(n,)`` altitude above the equatorial radius.
        inclination_rad: ``(n,)``.
    """

    altitude_m: np.ndarray
    inclination_rad: np.ndarray


@dataclass(frozen=True)
class Context:
    """What a controller knows before the first step of a batch: its benchmark version's public
    constants (never the fault, unless it is privileged).

    The hardware fields say what kind of actuators and sensors the version flies; each is ``None``
    where the version has no such thing. A version whose controllers need a new kind of public
    constant adds a field here: this is the interface every controller and submission reads.

    Attributes:
        n: episodes in the batch.
        benchmark_version: the version's name.
        dt_s: control step (the command is held over it).
        obs_dim, action_dim: widths of the observation and of the command.
        inertia_nominal_kgm2: diagonal of the *nominal* hub inertia.
        tau_max_nm: body-torque actuators: torque per body axis at command 1.
        wheels: reaction-wheel actuators: their constants.
        sensors: noisy sensors: their noise figures.
        rods: magnetorquer rods: their constants.
        orbit: each episode's orbit, where the version flies one.
        health_units: the units a controller may report the health of, in order (``health()``);
            empty where the version scores no diagnosis.
        fault: the true fault (a version's fault record), handed only to privileged controllers.
    """

    n: int
    benchmark_version: str
    dt_s: float
    obs_dim: int
    action_dim: int
    inertia_nominal_kgm2: np.ndarray
    tau_max_nm: float | None = None
    wheels: WheelKnowledge | None = None
    sensors: SensorKnowledge | None = None
    rods: RodKnowledge | None = None
    orbit: OrbitKnowledge | None = None
    health_units: tuple[str, ...] = ()
    fault: Any = None

    def public(self) -> dict[str, Any]:
        """The JSON-able public part (everything but ``fault``): what crosses into a sandbox."""
        return {f.name: _plain(getattr(self, f.name)) for f in fields(self) if f.name != "fault"}

    @classmethod
    def from_public(cls, doc: dict[str, Any]) -> Context:
        """Rebuild a fault-free context from ``public()``'s document (lists as float64 arrays, the
        hardware records from their fields' types)."""
        return _rebuild(cls, {k: v for k, v in doc.items() if k != "fault"})


def _rebuild(cls: type, doc: dict[str, Any]) -> Any:
    """An instance of dataclass ``cls`` from ``doc``: a field whose type names a dataclass is
    rebuilt from its dict the same way; a list of names becomes a tuple, any other list a float64
    array."""
    hints = typing.get_type_hints(cls)
    known = {f.name for f in fields(cls)}
    kwargs: dict[str, Any] = {}
    for name, value in doc.items():
        if name not in known:
            continue
        record = next(
            (t for t in typing.get_args(hints[name]) if isinstance(t, type) and is_dataclass(t)), None
        )
        kwargs[name] = (
            _rebuild(record, value) if record is not None and isinstance(value, dict) else _array(value)
        )
    return cls(**kwargs)


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray | tuple):
        return list(value) if isinstance(value, tuple) else value.tolist()
    if is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in fields(value)}
    return value


def _array(value: Any) -> Any:
    if isinstance(value, list) and all(isinstance(v, str) for v in value):  # names; [] is none
        return tuple(value)
    return np.asarray(value, dtype=float) if isinstance(value, list) else value


class Controller(ABC):
    """Base class of every controller, built-in or submitted."""

    privileged: ClassVar[bool] = False

    @abstractmethod
    def reset(self, n: int, context: Context) -> None:
        """Start ``n`` fresh episodes."""

    @abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """Commands ``(n, action_dim)`` in ``[-1, 1]`` for observations ``(n, obs_dim)``."""

    def health(self) -> np.ndarray | None:
        """Optional: after each ``act``, the health the controller believes each unit of
        ``context.health_units`` has, ``(n, units)`` integers: 0 healthy, 1 degraded, 2 failed.
        ``None`` (the default) reports nothing, scored as "never alarms". Only versions whose spec
        has a ``diagnosis`` ask for it."""
        return None


class Progress:
    """Where long work reports how far it got. This base reports nowhere; the command line
    subclasses it with a rich progress bar, and a cluster run forwards it from the workers.

    Work is counted in simulated steps of one batch (a 400-step rollout is 400 units) unless the
    caller sets another total; ``describe`` names what is running now.
    """

    def add_total(self, amount: float) -> None:
        """More work is planned: raise the total by ``amount``."""

    def advance(self, amount: float = 1.0) -> None:
        """``amount`` units of work are done."""

    def describe(self, text: str) -> None:
        """What is being done now (a short phrase)."""


NO_PROGRESS = Progress()
