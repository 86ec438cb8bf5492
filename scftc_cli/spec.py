"""Benchmark definitions as data: one frozen ``BenchmarkSpec`` per benchmark version.

Every number that defines a benchmark version lives in its spec object and nowhere else, so a
change to any of them is visible in one diff and travels with every result as the version string.
The layers below take a spec (or its version string) instead of module-level constants: scoring
reads ``spec.gates``, evaluation reads the taxonomy and cell sizes, the simulator reads the plant.
The written definition is ``docs/benchmark.md``; a test checks that every number here appears there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

from pydantic import BaseModel, ConfigDict

from scftc_cli.errors import UnknownNameError

if TYPE_CHECKING:
    import numpy as np

Split = Literal["train", "test"]
DEFAULT_BENCHMARK = "scftc-v1"


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


class RigidBodyPlant(_Frozen):
    """``scftc-v1``'s testbed: a rigid body with three body-axis torques (docs/benchmark.md)."""

    kind: Literal["rigid-body-torques"] = "rigid-body-torques"
    inertia_nominal_kgm2: tuple[float, float, float] = (10.0, 8.0, 6.0)
    dt_s: float = 0.5
    steps: int = 400
    tau_max_nm: float = 0.2
    sigma0_half_width: float = 0.5
    omega0_half_width_rad_s: float = 0.02


class GateSpec(_Frozen):
    """Thresholds of the three gates on the true pointing error."""

    settled_deg: float = 0.2
    operational_deg: float = 5.0
    touch_deg: float = 0.2
    dwell_steps: int = 20


class RigidBodySplit(_Frozen):
    """Parameter ranges of one split of ``scftc-v1``'s actuator-fault taxonomy."""

    inertia_scale: IntervalSet
    gain_magnitude: IntervalSet
    reversed_axes: tuple[int, ...]
    bias: IntervalSet


GATES: tuple[str, ...] = ("settled", "operational", "touch_once")


class BenchmarkSpec(_Frozen):
    """Everything that defines one benchmark version.

    Attributes:
        version: the string every result carries, e.g. ``scftc-v1``.
        plant: the testbed's physical constants (its ``kind`` selects the simulator).
        observation: the blocks of the observation vector, in order.
        action_dim: length of the command vector (each entry in [-1, 1]).
        splits: the fault taxonomy's parameter ranges per split.
        fault_classes: actuator classes, in table order.
        sensor_faults: sensor classes, evaluated on top of ``sensor_base_class`` faults.
        ranked_classes: the classes whose mean settled rate ranks deployable entries.
        n_faults, n_seeds: a full cell is ``n_faults x n_seeds`` episodes.
    """

    version: str
    title: str
    plant: RigidBodyPlant
    observation: tuple[ObservationField, ...]
    action_dim: int
    gates: GateSpec = GateSpec()
    splits: dict[str, RigidBodySplit]
    fault_classes: tuple[str, ...]
    sensor_faults: tuple[str, ...]
    sensor_base_class: str = "sign"
    ranked_classes: tuple[str, ...]
    n_faults: int = 50
    n_seeds: int = 10
    confidence: float = 0.95

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


V1 = BenchmarkSpec(
    version="scftc-v1",
    title="the source study's testbed: torques on the body, perfect sensors",
    plant=RigidBodyPlant(),
    observation=(
        ObservationField(name="sigma_meas", width=3, unit="MRP"),
        ObservationField(name="omega_meas", width=3, unit="rad/s"),
    ),
    action_dim=3,
    splits={
        "train": RigidBodySplit(
            inertia_scale=closed(0.8, 2.0),
            gain_magnitude=closed(0.5, 1.5),
            reversed_axes=(0, 1),
            bias=closed(-0.2, 0.2),
        ),
        "test": RigidBodySplit(
            inertia_scale=outside(0.7, 0.8, 2.0, 2.3),
            gain_magnitude=outside(0.3, 0.5, 1.5, 2.0),
            reversed_axes=(2, 3),
            bias=outside(-0.3, -0.2, 0.2, 0.3),
        ),
    },
    fault_classes=("sign", "gain", "gain_bias", "loss"),
    sensor_faults=("bias_0.1", "bias_0.2", "bias_0.3", "bias_0.5", "dropout", "stuck"),
    ranked_classes=("sign", "gain", "gain_bias"),
)

SPECS: dict[str, BenchmarkSpec] = {V1.version: V1}


def get_spec(version: str = DEFAULT_BENCHMARK) -> BenchmarkSpec:
    """The spec of ``version``; an unknown version suggests the closest one."""
    if version not in SPECS:
        raise UnknownNameError("benchmark version", version, SPECS)
    return SPECS[version]
