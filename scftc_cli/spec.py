"""Benchmark definitions as data: one frozen ``BenchmarkSpec`` per benchmark version.

Every number that defines a benchmark version lives in its spec object and nowhere else, so a
change to any of them is visible in one diff and travels with every result as the version string.
The layers below take a spec (or its version string) instead of module-level constants: scoring
reads ``spec.gates``, evaluation reads the taxonomy and cell sizes, the simulator reads the plant.
The written definition is ``docs/benchmark.md``; a test checks that every number here appears there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Generic, Literal, TypeVar

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


_R3 = 0.5773502691896258  # 1 / sqrt(3), the float64 nearest to it


class ReactionWheelPlant(_Frozen):
    """``scftc-v2``'s testbed: a rigid hub with four balanced reaction wheels (docs/benchmark-v2.md).

    Attributes:
        spin_axes: one unit spin axis per wheel, body frame (tetrahedral: any three independent).
        h_max_nms, omega_max_rpm: wheel momentum at the speed limit; ``Js = h_max / Omega_max``,
            transverse ``Jt = Js / 2``.
        u_max_nm: motor torque cap per wheel.
        coulomb_nm, viscous_nms, omega_linear_rad_s: nominal bearing friction ``fC0``, ``cV`` and
            the half width ``wLC`` of the zone where friction is linear in speed.
        wheel_speed0_half_width_rpm: initial wheel speeds are uniform in +- this, per wheel.
    """

    kind: Literal["reaction-wheels"] = "reaction-wheels"
    inertia_nominal_kgm2: tuple[float, float, float] = (10.0, 8.0, 6.0)
    spin_axes: tuple[tuple[float, float, float], ...] = (
        (_R3, _R3, _R3),
        (_R3, -_R3, -_R3),
        (-_R3, _R3, -_R3),
        (-_R3, -_R3, _R3),
    )
    h_max_nms: float = 2.0
    omega_max_rpm: float = 6000.0
    u_max_nm: float = 0.1
    coulomb_nm: float = 5e-4
    viscous_nms: float = 0.0
    omega_linear_rad_s: float = 3.0
    dt_s: float = 0.5
    steps: int = 400
    sigma0_half_width: float = 0.5
    omega0_half_width_rad_s: float = 0.02
    wheel_speed0_half_width_rpm: float = 1000.0

    @property
    def n_wheels(self) -> int:
        return len(self.spin_axes)


class SensorSuite(_Frozen):
    """``scftc-v2``'s sensors: noise figures a controller may know (never their draws).

    Attributes:
        star_tracker_heads: number of heads, each reporting the attitude with its own noise.
        star_tracker_noise_arcsec: white rotation noise per axis per sample, 1 sigma.
        gyro_arw_deg_sqrt_h: gyro angle random walk; per-sample sigma ``ARW / sqrt(dt)``.
        gyro_bias_deg_h: the constant gyro bias of an episode is uniform in +- this per axis.
        tachometer_noise_rad_s: white wheel-speed noise per sample, 1 sigma.
    """

    star_tracker_heads: int = 3
    star_tracker_noise_arcsec: float = 10.0
    gyro_arw_deg_sqrt_h: float = 0.15
    gyro_bias_deg_h: float = 0.5
    tachometer_noise_rad_s: float = 0.01


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


class WheelSplit(_Frozen):
    """Parameter ranges of one split of ``scftc-v2``'s fault taxonomy (actuator faults per wheel).

    Attributes:
        onset_s: the fault (actuator or sensor) starts at the first step ``k`` with ``k dt >= t_f``.
        reversed_wheels: the number of reversed wheels is drawn uniformly from these.
        gain_magnitude, bias: per-wheel effectiveness magnitude and offset (a fraction of ``u_max``).
        friction_multiplier: one wheel's Coulomb friction becomes this times ``fC0`` (``friction``).
        head_bias_deg: rotation offset of one star-tracker head (``st_bias``).
        gyro_bias_step_deg_s: size per axis of the gyro-bias step (``gyro_bias``), random signs.
    """

    inertia_scale: IntervalSet
    onset_s: IntervalSet
    reversed_wheels: tuple[int, ...]
    gain_magnitude: IntervalSet
    bias: IntervalSet
    friction_multiplier: IntervalSet
    head_bias_deg: IntervalSet
    gyro_bias_step_deg_s: IntervalSet


GATES: tuple[str, ...] = ("settled", "operational", "touch_once")


PlantT = TypeVar("PlantT", RigidBodyPlant, ReactionWheelPlant)
SplitT = TypeVar("SplitT", RigidBodySplit, WheelSplit)


class BenchmarkSpec(_Frozen, Generic[PlantT, SplitT]):
    """Everything that defines one benchmark version (generic in its plant and split types, so
    ``V1.plant`` is a ``RigidBodyPlant`` to the type checker and ``V2.plant`` a ``ReactionWheelPlant``).

    Attributes:
        version: the string every result carries, e.g. ``scftc-v1``.
        plant: the testbed's physical constants (its ``kind`` selects the simulator).
        sensors: the sensors' noise figures (``None``: perfect sensors).
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
    plant: PlantT
    sensors: SensorSuite | None = None
    observation: tuple[ObservationField, ...]
    action_dim: int
    gates: GateSpec = GateSpec()
    splits: dict[str, SplitT]
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


V1 = BenchmarkSpec[RigidBodyPlant, RigidBodySplit](
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

V2 = BenchmarkSpec[ReactionWheelPlant, WheelSplit](
    version="scftc-v2",
    title="the flight-like track: four reaction wheels, noisy redundant sensors, mid-flight faults",
    plant=ReactionWheelPlant(),
    sensors=SensorSuite(),
    observation=(
        ObservationField(name="star_tracker_heads", width=9, unit="MRP (three heads, zeros if invalid)"),
        ObservationField(name="star_tracker_valid", width=3, unit="1 valid, 0 invalid"),
        ObservationField(name="gyro", width=3, unit="rad/s"),
        ObservationField(name="tachometers", width=4, unit="rad/s"),
    ),
    action_dim=4,
    splits={
        "train": WheelSplit(
            inertia_scale=closed(0.8, 2.0),
            onset_s=closed(0.0, 30.0),
            reversed_wheels=(0, 1),
            gain_magnitude=closed(0.5, 1.5),
            bias=closed(-0.2, 0.2),
            friction_multiplier=closed(1.0, 20.0),
            head_bias_deg=closed(0.05, 0.3),
            gyro_bias_step_deg_s=closed(0.0, 0.015),
        ),
        "test": WheelSplit(
            inertia_scale=outside(0.7, 0.8, 2.0, 2.3),
            onset_s=IntervalSet(parts=(Interval(lo=30.0, hi=60.0, lo_closed=False),)),
            reversed_wheels=(2, 3),
            gain_magnitude=outside(0.3, 0.5, 1.5, 2.0),
            bias=outside(-0.3, -0.2, 0.2, 0.3),
            friction_multiplier=IntervalSet(parts=(Interval(lo=20.0, hi=60.0, lo_closed=False),)),
            head_bias_deg=IntervalSet(parts=(Interval(lo=0.3, hi=1.0, lo_closed=False),)),
            gyro_bias_step_deg_s=IntervalSet(parts=(Interval(lo=0.015, hi=0.03, lo_closed=False),)),
        ),
    },
    fault_classes=("sign", "gain", "gain_bias", "friction", "loss"),
    sensor_faults=("st_bias", "st_stuck", "st_outage", "gyro_bias"),
    ranked_classes=("sign", "gain", "gain_bias", "friction", "loss"),
)

SPECS: dict[str, BenchmarkSpec[Any, Any]] = {V1.version: V1, V2.version: V2}


def get_spec(version: str = DEFAULT_BENCHMARK) -> BenchmarkSpec:
    """The spec of ``version``; an unknown version suggests the closest one."""
    if version not in SPECS:
        raise UnknownNameError("benchmark version", version, SPECS)
    return SPECS[version]
