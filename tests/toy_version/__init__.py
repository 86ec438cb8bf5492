"""``toy-v0``: a benchmark version written outside the package, to prove that a version is one
folder plus one registry line (``scftc_cli.versions.register``) and that nothing else changes.

One axis, one fault class (a reversed or scaled actuator), tiny cells. The folder holds what any
version's folder holds: its spec as data, its simulator (pinned draws, plant, sensors, context),
its controllers and its ``Version`` record. It has no artifacts, trainers, sensor faults or
cross-check: a version need not.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from scftc_cli.protocol import Context, Controller
from scftc_cli.sim.episodes import Episodes, generator
from scftc_cli.sim.testbed import Plant, Sensors, Testbed
from scftc_cli.spec import (
    BenchmarkSpec,
    FaultClass,
    IntervalSet,
    ObservationField,
    PlantSpec,
    SensorSpec,
    SplitSpec,
    closed,
    outside,
)
from scftc_cli.versions import ControllerSpec, StudyPlan, Version

NAME = "toy-v0"


class AxisPlant(PlantSpec):
    """A single axis: ``I angle'' = g a tau_max``, the command ``a`` in [-1, 1]."""

    inertia_kgm2: float = 1.0
    tau_max_nm: float = 0.5
    dt_s: float = 0.5
    steps: int = 60
    angle0_half_width_rad: float = 0.5


class GainSplit(SplitSpec):
    gain_magnitude: IntervalSet


SPEC = BenchmarkSpec[AxisPlant, GainSplit, SensorSpec](
    version=NAME,
    title="one axis, one fault class",
    plant=AxisPlant(),
    observation=(
        ObservationField(name="angle", width=1, unit="rad"),
        ObservationField(name="rate", width=1, unit="rad/s"),
    ),
    action_dim=1,
    splits={
        "train": GainSplit(gain_magnitude=closed(0.5, 1.5)),
        "test": GainSplit(gain_magnitude=outside(0.2, 0.5, 1.5, 2.0)),
    },
    classes=(FaultClass(name="flip"),),
    sensor_classes=(),
    sensor_base_class="flip",
    ranked_classes=("flip",),
    n_faults=4,
    n_seeds=2,
)


@dataclass(frozen=True)
class AxisFault:
    """``gain`` ``(n, 1)`` (negative: reversed), ``bias`` ``(n, 1)`` (none), ``inertia_scale`` ``(n,)``."""

    gain: np.ndarray
    bias: np.ndarray
    inertia_scale: np.ndarray


@dataclass(frozen=True)
class AxisEpisodes(Episodes):
    fault: AxisFault
    angle0: np.ndarray


class AxisSim(Plant):
    name = "numpy"

    @classmethod
    def of(cls, episodes: AxisEpisodes) -> AxisSim:
        return cls(episodes)

    def __init__(self, episodes: AxisEpisodes) -> None:
        p = SPEC.plant
        self.gain = episodes.fault.gain[:, 0]
        self.angle, self.rate = episodes.angle0.copy(), np.zeros(episodes.n)
        self.accel_per_command = p.tau_max_nm / p.inertia_kgm2

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        self.rate = self.rate + SPEC.dt_s * self.gain * command[:, 0] * self.accel_per_command
        self.angle = self.angle + SPEC.dt_s * self.rate
        s = np.tan(self.angle / 4.0)  # the MRP of a rotation about one axis
        return s * s

    def states(self) -> dict[str, np.ndarray]:
        zero = np.zeros_like(self.angle)
        return {
            "sigma": np.stack((np.tan(self.angle / 4.0), zero, zero), axis=1),
            "omega_rad_s": np.stack((self.rate, zero, zero), axis=1),
        }


class PerfectSensors(Sensors):
    def observe(self, k: int, plant: Plant) -> np.ndarray:
        assert isinstance(plant, AxisSim)
        return np.stack((plant.angle, plant.rate), axis=1)


class AxisTestbed(Testbed):
    spec = SPEC
    plants = {"numpy": f"{__name__}:AxisSim", "reference": f"{__name__}:AxisSim"}

    def pinned(self, split, fault_class, sensor, n_faults, n_seeds, salt, start, stop) -> AxisEpisodes:
        ranges = SPEC.splits[split]
        gain, angle0, fault_index, seed_index = [], [], [], []
        for e in range(start, stop):
            i, j = divmod(e, n_seeds)
            rng = generator(NAME, split, fault_class, index=(0, i), salt=salt)
            magnitude = float(ranges.gain_magnitude.sample(rng, 1)[0])
            gain.append(-magnitude if rng.random() < 0.5 else magnitude)
            half = SPEC.plant.angle0_half_width_rad
            rng = generator(NAME, split, fault_class, index=(1, i, j), salt=salt)
            angle0.append(rng.uniform(-half, half))
            fault_index.append(i)
            seed_index.append(j)
        m = stop - start
        return AxisEpisodes(
            benchmark=NAME,
            split=split,
            fault_class=fault_class,
            sensor=sensor,
            fault_index=np.array(fault_index),
            seed_index=np.array(seed_index),
            fault=AxisFault(np.array(gain)[:, None], np.zeros((m, 1)), np.ones(m)),
            angle0=np.array(angle0),
        ).readonly()

    def sensors(self, episodes: Episodes) -> Sensors:
        return PerfectSensors()

    def context(self, episodes: AxisEpisodes, privileged: bool) -> Context:  # type: ignore[override]
        p = SPEC.plant
        return Context(
            n=episodes.n,
            benchmark_version=NAME,
            dt_s=p.dt_s,
            obs_dim=SPEC.obs_dim,
            action_dim=SPEC.action_dim,
            inertia_nominal_kgm2=np.array([p.inertia_kgm2]),
            tau_max_nm=p.tau_max_nm,
            fault=episodes.fault.gain if privileged else None,
        )


TESTBED = AxisTestbed()


class PD(Controller):
    """Fault-unaware PD on the measured angle: ``a = -(angle + 2 rate)``."""

    def reset(self, n: int, context: Context) -> None:
        self.gain = np.ones((n, 1))

    def act(self, obs: np.ndarray) -> np.ndarray:
        return np.clip(-(obs[:, :1] + 2.0 * obs[:, 1:2]) / self.gain, -1.0, 1.0)


class Teacher(PD):
    """Privileged: the PD divided by the true gain."""

    privileged = True

    def reset(self, n: int, context: Context) -> None:
        self.gain = np.asarray(context.fault)


VERSION = Version(
    spec=SPEC,
    testbed=f"{__name__}:TESTBED",
    controllers=(
        ControllerSpec("pd", f"{__name__}:PD", "fault-unaware PD on the angle", family="reference"),
        ControllerSpec(
            "teacher", f"{__name__}:Teacher", "privileged: the PD, true gain", True, family="oracle"
        ),
    ),
    folder=Path(__file__).resolve().parent,
    study=StudyPlan(sensors_in_battery=True, regime_rule="no sensor faults"),
)

SUBMISSION_SOURCE = f'''"""A submitted controller of {NAME}: the PD through a gain identified by a probe."""

import numpy as np

SUBMISSION = {{
    "name": "toy_probe",
    "version": "1.0.0",
    "authors": ["a tester"],
    "description": "probes the axis once, then flies the PD through the identified gain",
    "entry": "Probe",
    "license": "MIT",
    "benchmark": "{NAME}",
}}


class Probe:
    def reset(self, n, context):
        self.k, self.scale = 0, context.dt_s * context.tau_max_nm / float(context.inertia_nominal_kgm2[0])
        self.rate0 = np.zeros((n, 1))
        self.gain = np.ones((n, context.action_dim))

    def act(self, obs):
        self.k += 1
        if self.k == 1:
            self.rate0 = obs[:, 1:2].copy()
            return np.full((len(obs), 1), 0.1)
        if self.k == 2:
            self.gain = (obs[:, 1:2] - self.rate0) / (0.1 * self.scale)
        return np.clip(-(obs[:, :1] + 2.0 * obs[:, 1:2]) / self.gain, -1.0, 1.0)
'''
