"""The benchmark definition (SPEC.md sections 1-3) as one frozen object.

Every number that defines ``scftc-v1`` lives here and nowhere else, so that a change to any of
them is visible in one diff and travels with every result as ``BENCHMARK_VERSION``.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict

from scftc_cli import BENCHMARK_VERSION

Split = Literal["train", "test"]
FAULT_CLASSES: tuple[str, ...] = ("sign", "gain", "gain_bias", "loss")
SENSOR_FAULTS: tuple[str, ...] = ("bias_0.1", "bias_0.2", "bias_0.3", "bias_0.5", "dropout", "stuck")
SPLITS: tuple[str, ...] = ("test", "train")


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
        x = np.asarray(x)
        above = x >= self.lo if self.lo_closed else x > self.lo
        below = x <= self.hi if self.hi_closed else x < self.hi
        return above & below

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """Map ``u`` in [0, 1) onto the interval, never onto an open end."""
        if self.lo_closed:
            x = self.lo + u * self.length
            return np.minimum(x, self.hi if self.hi_closed else np.nextafter(self.hi, -np.inf))
        x = self.hi - u * self.length  # (lo, hi]: measure from the closed top end
        return np.maximum(x, np.nextafter(self.lo, np.inf))


class IntervalSet(_Frozen):
    """A disjoint union of intervals, sampled uniformly by length (SPEC section 2)."""

    parts: tuple[Interval, ...]

    def contains(self, x: np.ndarray | float) -> np.ndarray:
        x = np.asarray(x)
        return np.logical_or.reduce([p.contains(x) for p in self.parts])

    def sample(self, rng: np.random.Generator, size: int | tuple[int, ...]) -> np.ndarray:
        lengths = np.array([p.length for p in self.parts])
        ends = np.cumsum(lengths)
        s = rng.random(size) * ends[-1]  # a position along the concatenated union
        which = np.minimum(np.searchsorted(ends, s, side="right"), len(self.parts) - 1)
        u = np.clip((s - (ends - lengths)[which]) / lengths[which], 0.0, np.nextafter(1.0, 0.0))
        out = np.empty(np.shape(s))
        for i, part in enumerate(self.parts):
            out[which == i] = part.from_unit(u[which == i])
        return out


def _closed(lo: float, hi: float) -> IntervalSet:
    return IntervalSet(parts=(Interval(lo=lo, hi=hi),))


def _outside(lo_a: float, lo_b: float, hi_a: float, hi_b: float) -> IntervalSet:
    """``[lo_a, lo_b) U (hi_a, hi_b]``: the held-out band on both sides of a train range."""
    return IntervalSet(
        parts=(
            Interval(lo=lo_a, hi=lo_b, hi_closed=False),
            Interval(lo=hi_a, hi=hi_b, lo_closed=False),
        )
    )


class SplitSpec(_Frozen):
    """Parameter ranges of one split of the actuator-fault taxonomy."""

    inertia_scale: IntervalSet
    gain_magnitude: IntervalSet
    reversed_axes: tuple[int, ...]
    bias: IntervalSet


class PlantSpec(_Frozen):
    """The rigid spacecraft and its episode (SPEC section 1)."""

    inertia_nominal_kgm2: tuple[float, float, float] = (10.0, 8.0, 6.0)
    dt_s: float = 0.5
    steps: int = 400
    tau_max_nm: float = 0.2
    sigma0_half_width: float = 0.5
    omega0_half_width_rad_s: float = 0.02


class GateSpec(_Frozen):
    """Thresholds of the three gates on the true pointing error (SPEC section 3)."""

    settled_deg: float = 0.2
    operational_deg: float = 5.0
    touch_deg: float = 0.2
    dwell_steps: int = 20


class BenchmarkSpec(_Frozen):
    version: str = BENCHMARK_VERSION
    plant: PlantSpec = PlantSpec()
    gates: GateSpec = GateSpec()
    splits: dict[str, SplitSpec]
    fault_classes: tuple[str, ...] = FAULT_CLASSES
    sensor_faults: tuple[str, ...] = SENSOR_FAULTS
    n_faults: int = 50
    n_seeds: int = 10
    confidence: float = 0.95


SPEC = BenchmarkSpec(
    splits={
        "train": SplitSpec(
            inertia_scale=_closed(0.8, 2.0),
            gain_magnitude=_closed(0.5, 1.5),
            reversed_axes=(0, 1),
            bias=_closed(-0.2, 0.2),
        ),
        "test": SplitSpec(
            inertia_scale=_outside(0.7, 0.8, 2.0, 2.3),
            gain_magnitude=_outside(0.3, 0.5, 1.5, 2.0),
            reversed_axes=(2, 3),
            bias=_outside(-0.3, -0.2, 0.2, 0.3),
        ),
    }
)

INERTIA_NOMINAL = np.array(SPEC.plant.inertia_nominal_kgm2)
