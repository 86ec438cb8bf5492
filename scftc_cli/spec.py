"""What a benchmark version is, as data: the schema of every version's frozen ``BenchmarkSpec``.

Every number that defines a benchmark version lives in its spec object (``versions/<name>/spec.py``)
and nowhere else, so a change to any of them is visible in one diff and travels with every result
as the version string. The layers below take a spec instead of module-level constants: scoring
reads ``spec.gates``, evaluation reads the taxonomy (``classes``, ``sensor_classes``, ``splits``)
and cell sizes, the simulator reads the plant. Each version's written definition lives in ``docs/``;
a test checks that every value of its spec appears there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Generic, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, model_validator

from scftc_cli import versions
from scftc_cli.errors import UnknownNameError, UsageError

if TYPE_CHECKING:
    import numpy as np

Split = Literal["train", "test"]
DEFAULT_BENCHMARK: str = versions.default_version()
"""The version every command flies unless told otherwise: the first registered (``versions.VERSIONS``)."""


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Interval(_Frozen):
    """A real interval with explicit open/closed ends, e.g. ``(1.5, 2.0]``."""

    lo: float
    hi: float
    lo_closed: bool = True
    hi_closed: bool = True

    @property
    def length(self) -> float:
        return self.hi - self.lo

    def contains(self, x: np.ndarray | float) -> np.ndarray:
        import numpy as np  # not at module level: the command line's help needs no numpy

        x = np.asarray(x)
        above = x >= self.lo if self.lo_closed else x > self.lo
        below = x <= self.hi if self.hi_closed else x < self.hi
        return above & below

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """Map ``u`` in [0, 1) onto the interval, never onto an open end."""
        import numpy as np

        if self.lo_closed:
            x = self.lo + u * self.length
            return np.minimum(x, self.hi if self.hi_closed else np.nextafter(self.hi, -np.inf))
        x = self.hi - u * self.length  # (lo, hi]: measure from the closed top end
        return np.maximum(x, np.nextafter(self.lo, np.inf))

    def __str__(self) -> str:
        return f"{'[' if self.lo_closed else '('}{self.lo:g}, {self.hi:g}{']' if self.hi_closed else ')'}"


class IntervalSet(_Frozen):
    """A disjoint union of intervals, sampled uniformly by length (``docs/benchmark.md``)."""

    parts: tuple[Interval, ...]

    def contains(self, x: np.ndarray | float) -> np.ndarray:
        import numpy as np

        x = np.asarray(x)
        return np.logical_or.reduce([p.contains(x) for p in self.parts])

    def sample(self, rng: np.random.Generator, size: int | tuple[int, ...]) -> np.ndarray:
        import numpy as np

        lengths = np.array([p.length for p in self.parts])
        ends = np.cumsum(lengths)
        s = rng.random(size) * ends[-1]  # a position along the concatenated union
        which = np.minimum(np.searchsorted(ends, s, side="right"), len(self.parts) - 1)
        u = np.clip((s - (ends - lengths)[which]) / lengths[which], 0.0, np.nextafter(1.0, 0.0))
        out = np.empty(np.shape(s))
        for i, part in enumerate(self.parts):
            out[which == i] = part.from_unit(u[which == i])
        return out

    def __str__(self) -> str:
        return " U ".join(str(p) for p in self.parts)


def closed(lo: float, hi: float) -> IntervalSet:
    """``[lo, hi]``."""
    return IntervalSet(parts=(Interval(lo=lo, hi=hi),))


def outside(lo_a: float, lo_b: float, hi_a: float, hi_b: float) -> IntervalSet:
    """``[lo_a, lo_b) U (hi_a, hi_b]``: the held-out band on both sides of a train range."""
    return IntervalSet(
        parts=(
            Interval(lo=lo_a, hi=lo_b, hi_closed=False),
            Interval(lo=hi_a, hi=hi_b, lo_closed=False),
        )
    )


class ObservationField(_Frozen):
    """One block of the observation vector a controller receives every step."""

    name: str
    width: int
    unit: str


class PlantSpec(_Frozen):
    """What every version's plant declares (its own model adds its physical constants)."""

    dt_s: float
    steps: int


class SensorSpec(_Frozen):
    """A version's sensor noise figures, a controller may know them (its own model adds them)."""


class SplitSpec(_Frozen):
    """The parameter ranges of one split of a version's fault taxonomy (its own model adds them).

    A split whose model has an ``onset_s`` range starts its faults mid-flight (``BenchmarkSpec.has_onset``).
    """


class FaultClass(_Frozen):
    """An actuator fault class as data: which of a split's ranges its faults draw, beyond the
    inertia scale and the reversed actuators that every class draws (in the sampler's order).

    Attributes:
        name: the class's name on the command line and in tables.
        magnitude: effectiveness magnitudes drawn from ``gain_magnitude`` (false: sign only, 1).
        bias: per-actuator offsets drawn from ``bias``.
        friction: one actuator's friction multiplied by a draw of ``friction_multiplier``.
        dead: one actuator dead (effectiveness 0).
    """

    name: str
    magnitude: bool = True
    bias: bool = False
    friction: bool = False
    dead: bool = False


class SensorFaultClass(_Frozen):
    """A sensor fault class as data; its faults sit on ``sensor_base_class`` faults.

    Attributes:
        name: the fault's name on the command line and in tables.
        kind: what the version's sensors do (each version's sensor model reads the kinds it defines).
        angle_deg: the size of a constant attitude offset, for the kinds that have one.
    """

    name: str
    kind: str
    angle_deg: float | None = None


GATES: tuple[str, ...] = ("settled", "operational", "touch_once")
"""The gates every cell is scored on, in table order: the field names of every record of them."""


class GateSpec(_Frozen):
    """The gates on the true pointing error: the one place that says what each one compares.

    ``settled`` and ``operational`` compare the largest error over the final ``dwell_steps`` with
    their threshold; ``touch_once`` compares the smallest error over the whole episode with its own.
    """

    settled_deg: float = 0.2
    operational_deg: float = 5.0
    touch_deg: float = 0.2
    dwell_steps: int = 20

    def thresholds_deg(self) -> dict[str, float]:
        """Each gate of ``GATES`` and its threshold in deg."""
        return {
            "settled": self.settled_deg,
            "operational": self.operational_deg,
            "touch_once": self.touch_deg,
        }

    def passed(self, dwell_max_error_deg: np.ndarray, min_error_deg: np.ndarray) -> dict[str, np.ndarray]:
        """``(n,)`` bool outcome of each gate of ``GATES`` from each episode's largest error over the
        final dwell window and smallest error over the episode (deg, ``(n,)`` each)."""
        thresholds = self.thresholds_deg()
        return {
            "settled": dwell_max_error_deg <= thresholds["settled"],
            "operational": dwell_max_error_deg <= thresholds["operational"],
            "touch_once": min_error_deg <= thresholds["touch_once"],
        }


PlantT = TypeVar("PlantT", bound=PlantSpec)
SplitT = TypeVar("SplitT", bound=SplitSpec)
SensorsT = TypeVar("SensorsT", bound=SensorSpec)


class DiagnosisSpec(_Frozen):
    """A version that scores what a controller's fault detection says (``Controller.health``).

    Attributes:
        units: the actuators and sensors whose health a controller may report, in order; each step
            one code per unit: 0 healthy, 1 degraded, 2 failed.
        false_alarm_budget: the largest fraction of healthy episodes (nominal ones, or before the
            onset) in which an entry may raise an alarm before the board flags it.
        detection: what counts as detecting a fault (docs/diagnosis.md). ``any_alarm``: any unit
            reported not healthy at or after the onset. ``faulted_unit``: only a report at or
            after the onset that names a unit the fault left not healthy; a report naming a
            healthy unit, at any time, is a false isolation.
        ranked: the board ranks the diagnosis on its own, beside the settled ranking (needs the
            ``faulted_unit`` rule: under ``any_alarm`` an alarm raised at step 0 and never lowered
            would detect every fault with no delay).
    """

    units: tuple[str, ...]
    false_alarm_budget: float = 0.01
    detection: Literal["any_alarm", "faulted_unit"] = "any_alarm"
    ranked: bool = False

    @model_validator(mode="after")
    def _ranked_needs_the_faulted_unit_rule(self) -> DiagnosisSpec:
        if self.ranked and self.detection != "faulted_unit":
            raise ValueError("a ranked diagnosis needs detection='faulted_unit'")
        return self


HEALTH_CODES = {0: "healthy", 1: "degraded", 2: "failed"}


class AdmissionRule(_Frozen):
    """When a fault class may rank: it must leave room to win and must not be won without knowing
    the fault. Checked on the train split before a version is frozen, reported held out after.

    Attributes:
        oracle: the privileged controller that shows the class can be flown.
        oracle_at_least: the smallest settled rate the oracle must reach on the class.
        unaware: the fault-unaware, train-tuned controller that shows the class needs fault
            tolerance.
        unaware_at_most: the largest settled rate the unaware controller may reach on it.
        split: where the rule is decided (the held-out split only reports it).
    """

    oracle: str
    oracle_at_least: float
    unaware: str
    unaware_at_most: float
    split: str = "train"

    def admits(self, oracle_rate: float, unaware_rate: float) -> bool:
        """Whether a class with these settled rates (fractions) may rank."""
        return oracle_rate >= self.oracle_at_least and unaware_rate <= self.unaware_at_most


class BenchmarkSpec(_Frozen, Generic[PlantT, SplitT, SensorsT]):
    """Everything that defines one benchmark version, as data (generic in its plant, split and
    sensor models, so that each version's code sees its own types).

    Attributes:
        version: the string every result carries.
        plant: the testbed's physical constants.
        sensors: the sensors' noise figures (``None``: perfect sensors).
        observation: the blocks of the observation vector, in order.
        action_dim: length of the command vector (each entry in [-1, 1]).
        splits: the fault taxonomy's parameter ranges per split.
        classes: the actuator fault classes, in table order.
        sensor_classes: the sensor fault classes, evaluated on top of ``sensor_base_class`` faults.
        ranked_classes: the classes whose mean settled rate ranks deployable entries.
        n_faults, n_seeds: a full cell is ``n_faults x n_seeds`` episodes.
        diagnosis: what a controller's fault detection is scored on (``None``: not scored).
        admission: the rule a class passes to be in ``ranked_classes`` (``None``: the version
            predates it).
    """

    version: str
    title: str
    plant: PlantT
    sensors: SensorsT | None = None
    observation: tuple[ObservationField, ...]
    action_dim: int
    gates: GateSpec = GateSpec()
    splits: dict[str, SplitT]
    classes: tuple[FaultClass, ...]
    sensor_classes: tuple[SensorFaultClass, ...]
    sensor_base_class: str = "sign"
    ranked_classes: tuple[str, ...]
    n_faults: int = 50
    n_seeds: int = 10
    confidence: float = 0.95
    diagnosis: DiagnosisSpec | None = None
    admission: AdmissionRule | None = None

    @property
    def fault_classes(self) -> tuple[str, ...]:
        """The actuator classes' names, in table order."""
        return tuple(c.name for c in self.classes)

    @property
    def sensor_faults(self) -> tuple[str, ...]:
        """The sensor faults' names, in table order."""
        return tuple(c.name for c in self.sensor_classes)

    def fault_class(self, name: str) -> FaultClass:
        """The actuator class ``name``."""
        return self.classes[self.fault_classes.index(name)]

    def sensor_class(self, name: str) -> SensorFaultClass:
        """The sensor fault ``name``."""
        return self.sensor_classes[self.sensor_faults.index(name)]

    def check_cell(self, split: str, fault_class: str, sensor: str | None = None) -> None:
        """Raise ``UnknownNameError`` naming the valid choices if the cell does not exist, and a
        ``UsageError`` for a sensor fault on another class than ``sensor_base_class``."""
        if split not in self.splits:
            raise UnknownNameError("split", split, self.splits)
        if fault_class not in self.fault_classes:
            raise UnknownNameError("fault class", fault_class, self.fault_classes)
        if sensor is not None:
            if sensor not in self.sensor_faults:
                raise UnknownNameError("sensor fault", sensor, self.sensor_faults)
            if fault_class != self.sensor_base_class:
                raise UsageError(f"sensor faults are defined on top of `{self.sensor_base_class}` faults")

    @property
    def has_onset(self) -> bool:
        """Whether faults start mid-flight: the taxonomy's splits draw an onset time."""
        return "onset_s" in type(self.splits["test"]).model_fields

    @property
    def obs_dim(self) -> int:
        return sum(f.width for f in self.observation)

    @property
    def episodes_per_cell(self) -> int:
        return self.n_faults * self.n_seeds

    @property
    def steps(self) -> int:
        return self.plant.steps

    @property
    def dt_s(self) -> float:
        return self.plant.dt_s


def get_spec(version: str | None = None) -> BenchmarkSpec[Any, Any, Any]:
    """The spec of registered version ``version`` (the default's when ``None``); an unknown version
    suggests the closest one."""
    return versions.get_spec(version)


def __getattr__(name: str) -> Any:
    """A registered version's spec by the short name its folder gives it (``versions.spec_alias``):
    kept so that code written against the specs' old home still reads them."""
    spec = None if name.startswith("_") else versions.spec_by_alias(name)
    if spec is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return spec
