"""``toy-d0``: the toy axis with what ``scftc-v3`` brings to the framework, and nothing else: two
pointing windows (the target angle steps at mid-episode) and a scored diagnosis (one unit, the
axis; its fault starts at a drawn onset). Registered by tests that need it, like ``toy-v0``."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from scftc_cli.protocol import Context, Controller
from scftc_cli.sim.episodes import generator
from scftc_cli.sim.testbed import DiagnosisTruth
from scftc_cli.spec import BenchmarkSpec, DiagnosisSpec, FaultClass, SensorSpec, closed
from scftc_cli.versions import ControllerSpec, StudyPlan, Version
from tests.toy_version import SPEC as AXIS
from tests.toy_version import AxisEpisodes, AxisPlant, AxisSim, AxisTestbed, GainSplit

NAME = "toy-d0"
TARGET_RAD = 0.3  # the second window's target angle

SPEC = BenchmarkSpec[AxisPlant, GainSplit, SensorSpec](
    **{
        **AXIS.model_dump(exclude={"plant", "splits", "classes", "version", "diagnosis"}),
        "version": NAME,
        "plant": AXIS.plant.model_copy(update={"steps": 200}),  # two 50 s windows: room to settle twice
        "splits": AXIS.splits,
        "classes": (FaultClass(name="flip"),),
        "diagnosis": DiagnosisSpec(units=("axis",), false_alarm_budget=0.01),
    }
)


@dataclass(frozen=True)
class OnsetEpisodes(AxisEpisodes):
    onset_step: np.ndarray


class TwoWindowSim(AxisSim):
    """The axis, whose gain is 1 before the onset and the fault's after, pointed at 0 rad in the
    first window and at ``TARGET_RAD`` in the second: ``step`` returns the error to the target."""

    @classmethod
    def of(cls, episodes: OnsetEpisodes) -> TwoWindowSim:  # type: ignore[override]
        return cls(episodes)

    def __init__(self, episodes: OnsetEpisodes) -> None:
        super().__init__(episodes)
        self.fault_gain, self.onset = self.gain, episodes.onset_step

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        self.gain = np.where(k >= self.onset, self.fault_gain, 1.0)
        super().step(k, command)
        s = np.tan((self.angle - target(k)) / 4.0)
        return s * s


def target(k: int) -> float:
    return 0.0 if k < SPEC.steps // 2 else TARGET_RAD


class DiagnosedTestbed(AxisTestbed):
    spec = SPEC
    plants = {"numpy": f"{__name__}:TwoWindowSim", "reference": f"{__name__}:TwoWindowSim"}

    def pinned(self, split, fault_class, sensor, n_faults, n_seeds, salt, start, stop) -> OnsetEpisodes:
        base = super().pinned(split, fault_class, sensor, n_faults, n_seeds, salt, start, stop)
        onset = [
            int(closed(5, 50).sample(generator(NAME, split, "onset", index=(i,), salt=salt), 1)[0])
            for i in base.fault_index
        ]
        return OnsetEpisodes(**{**base.__dict__, "benchmark": NAME, "onset_step": np.array(onset)}).readonly()

    def windows(self) -> tuple[int, ...]:
        return (SPEC.steps // 2, SPEC.steps)

    def diagnosis_truth(self, episodes: OnsetEpisodes) -> DiagnosisTruth:  # type: ignore[override]
        reversed_axis = episodes.fault.gain[:, :1] < 0  # reversed: failed (2); scaled: degraded (1)
        return DiagnosisTruth(episodes.onset_step, np.where(reversed_axis, 2, 1))

    def context(self, episodes: OnsetEpisodes, privileged: bool) -> Context:  # type: ignore[override]
        context = super().context(episodes, privileged)
        truth = self.diagnosis_truth(episodes) if privileged else None
        return replace(context, benchmark_version=NAME, health_units=("axis",), fault=(context.fault, truth))


TESTBED = DiagnosedTestbed()


class Tracker(Controller):
    """Fault-unaware PD on the error to the current target (reads the step count itself)."""

    def reset(self, n: int, context: Context) -> None:
        self.k, self.gain = 0, np.ones((n, 1))

    def act(self, obs: np.ndarray) -> np.ndarray:
        error = obs[:, :1] - target(self.k)
        self.k += 1
        return np.clip(-(error + 2.0 * obs[:, 1:2]) / self.gain, -1.0, 1.0)


class Oracle(Tracker):
    """Privileged: the true gain from the onset on, and a perfect diagnosis."""

    privileged = True

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        self.fault_gain, self.truth = np.asarray(context.fault[0]), context.fault[1]

    def act(self, obs: np.ndarray) -> np.ndarray:
        self.gain = np.where(self.k >= self.truth.onset_step[:, None], self.fault_gain, 1.0)
        return super().act(obs)

    def health(self) -> np.ndarray:
        return np.where(self.k - 1 >= self.truth.onset_step[:, None], self.truth.codes, 0)


VERSION = Version(
    spec=SPEC,
    testbed=f"{__name__}:TESTBED",
    controllers=(
        ControllerSpec(
            "tracker", f"{__name__}:Tracker", "fault-unaware PD on the target", family="reference"
        ),
        ControllerSpec(
            "oracle", f"{__name__}:Oracle", "privileged: true gain, perfect diagnosis", True, family="oracle"
        ),
    ),
    folder=Path(__file__).resolve().parent,
    study=StudyPlan(sensors_in_battery=True, regime_rule="no sensor faults"),
)
