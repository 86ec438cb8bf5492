"""``scftc-v4``'s draws: v3's draws (``versions/v3/sim/faults.py``: streams, order, missions,
orbits, sensor faults, noise), keyed by ``scftc-v4``, with two recalibrated fault kinds added
after v3's own draws of the same fault:

- ``intermittent`` (``flicker``): v3's burst draws, then the wheel's gain is multiplied by
  ``flicker_gain`` during each burst (it drives backwards) as well as sticking (its friction burst);
- ``incipient`` (``creep``): v3's friction-ramp draws, then the creep's end gain and duration (the
  wheel's gain falls linearly from 1 at the onset to the end gain over the duration, then stays,
  as its friction ramps), then the wheel that is dead from the onset, among the others.

The ``rod`` class draws its stored momentum from the split's ``rod_stored_momentum_nms``
(``V4Split.for_class``). Every stream key starts with the version, so no v4 draw equals a v3 one.
"""

from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np

from scftc_cli.versions.v3.sim import faults as v3
from scftc_cli.versions.v3.sim.faults import AgileEpisodes, DrawnFault, draw_cell
from scftc_cli.versions.v3.spec import AgilePlant
from scftc_cli.versions.v4.spec import V4, V4FaultClass, V4Split


def the_wheel(values: np.ndarray, what: str) -> int:
    """The one wheel whose entry of ``values`` ``(m,)`` is off 1 (a class that faults one wheel)."""
    wheels = np.flatnonzero(values != 1.0)
    if len(wheels) != 1:
        raise ValueError(
            f"expected one wheel with a {what}, got {len(wheels)}: the split's range must exclude 1"
        )
    return int(wheels[0])


def sample_fault(
    split: V4Split, kind: V4FaultClass, plant: AgilePlant, rng: np.random.Generator
) -> DrawnFault:
    """One fault of class ``kind``: v3's draws (``v3.sample_fault``), then, for ``flicker``, the
    burst wheel's gain factor (no draw: ``flicker_gain``), and for ``creep``, the end gain, the
    duration and the dead wheel."""
    drawn = v3.sample_fault(split, kind, plant, rng)
    m = plant.n_wheels
    creep, flicker = np.zeros(m), np.ones(m)
    if kind.flicker:
        flicker[the_wheel(drawn.burst_multiplier, "friction burst")] = split.flicker_gain
    gain = drawn.gain.copy()
    floor = np.zeros(m)
    if kind.creep:
        end = float(split.creep_end_gain.sample(rng, 1)[0])
        duration_s = float(split.creep_duration_s.sample(rng, 1)[0])
        wheel = the_wheel(drawn.friction_ramp_end, "friction ramp")
        creep[wheel], floor[wheel] = (end - 1.0) * plant.dt_s / duration_s, end
        gain[(wheel + 1 + int(rng.integers(m - 1))) % m] = 0.0
    return replace(drawn, gain=gain, gain_creep_per_step=creep, gain_creep_floor=floor, burst_gain=flicker)


@functools.lru_cache(maxsize=64)
def pinned_episodes(
    split: str,
    fault_class: str,
    sensor: str | None,
    n_faults: int,
    n_seeds: int,
    salt: bytes,
    start: int,
    stop: int,
) -> AgileEpisodes:
    """Episodes ``start..stop-1`` of a pinned (or, with ``salt``, sealed) ``scftc-v4`` cell,
    fault-major (``v3.draw_cell``). Cached; read-only."""
    return draw_cell(V4, sample_fault, split, fault_class, sensor, n_seeds, salt, start, stop)
