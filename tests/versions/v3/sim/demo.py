"""Random v3 batches for tests and the benchmark script: a stand-in for the episode generator.

Not the benchmark's draws (those belong to the episode generator, keyed by ``SeedSequence`` like
v2's): plain uniform draws over wide ranges, enough to exercise every branch of the plant.
"""

from __future__ import annotations

import math

import numpy as np

from scftc_cli.versions.v2.sim.dynamics import RPM_TO_RAD_S
from scftc_cli.versions.v2.sim.faults import SensorFault
from scftc_cli.versions.v3.sim.dynamics import PlantFault
from scftc_cli.versions.v3.sim.environment import EARTH_RADIUS_M, Environment
from scftc_cli.versions.v3.sim.sensors import MAG_BIAS, MAG_SPIKE, MagnetometerFault, SensorEpisodes


def unit_vectors(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` uniform random unit vectors ``(n, 3)``."""
    v = rng.standard_normal((n, 3))
    return v / np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])[:, None]


def random_environment(rng: np.random.Generator, n: int) -> Environment:
    """Altitude 500-700 km, inclination 40-98 deg, random node, latitude and Earth angle; residual
    dipole up to 1 A m^2 in a random direction; a 2 m^2 facet with a random normal and its centre
    of pressure 0.05-0.3 m off the centre of mass; a random Sun direction."""
    return Environment(
        semi_major_axis_m=EARTH_RADIUS_M + rng.uniform(500e3, 700e3, n),
        inclination_rad=np.radians(rng.uniform(40.0, 98.0, n)),
        raan_rad=rng.uniform(0.0, 2.0 * math.pi, n),
        arg_latitude0_rad=rng.uniform(0.0, 2.0 * math.pi, n),
        earth_angle_rad=rng.uniform(0.0, 2.0 * math.pi, n),
        residual_dipole_am2=rng.uniform(0.0, 1.0, n)[:, None] * unit_vectors(rng, n),
        sun_direction=unit_vectors(rng, n),
        facet_area_m2=np.full(n, 2.0),
        facet_normal=unit_vectors(rng, n),
        facet_cop_m=rng.uniform(0.05, 0.3, n)[:, None] * unit_vectors(rng, n),
    )


def random_faults(
    rng: np.random.Generator,
    n: int,
    steps: int = 2400,
    bursts: int = 6,
    *,
    bursts_start_below: int | None = None,
    sort_bursts: bool = True,
    longest_burst: int = 120,
    onset_below: int | None = None,
) -> PlantFault:
    """Every kind of v3 actuator fault, mixed: scaled and reversed gains, offsets, a dead wheel in
    every fifth episode, constant friction, ramps, bursts, rod gains in {1, -1, 0, 0.5}. Bursts
    start below ``bursts_start_below`` (default ``steps``; sorted per episode unless told not to)
    and last less than ``longest_burst`` steps (some empty); onsets fall below ``onset_below``
    (default half the episode)."""
    m = 4
    sign = np.where(rng.random((n, m)) < 0.2, -1.0, 1.0)
    gain = sign * rng.uniform(0.3, 2.0, (n, m))
    gain[::5, 2] = 0.0
    wheel = rng.integers(0, m, n)
    rows = np.arange(n)
    friction, ramp, burst = np.ones((n, m)), np.ones((n, m)), np.ones((n, m))
    friction[rows, wheel] = rng.uniform(1.0, 20.0, n)
    ramp[rows, (wheel + 1) % m] = rng.uniform(1.0, 60.0, n)
    burst[rows, (wheel + 2) % m] = rng.uniform(10.0, 60.0, n)
    start = rng.integers(0, steps if bursts_start_below is None else bursts_start_below, (n, bursts))
    start = np.sort(start, axis=1) if sort_bursts else start
    end = start + rng.integers(0, longest_burst, (n, bursts))
    return PlantFault(
        gain=gain,
        bias=rng.uniform(-0.3, 0.3, (n, m)),
        friction_multiplier=friction,
        friction_ramp_end=ramp,
        burst_multiplier=burst,
        burst_start_step=start,
        burst_end_step=end,
        rod_gain=rng.choice(np.array([1.0, -1.0, 0.0, 0.5]), (n, 3)),
        onset_step=rng.integers(0, steps // 2 if onset_below is None else onset_below, n),
    )


def random_plant_args(rng: np.random.Generator, n: int, faults: bool = True) -> dict:
    """Constructor arguments of ``n`` v3 episodes with v2's initial conditions (attitude error per
    axis in [-0.5, 0.5], rates up to 0.02 rad/s, wheels up to 1000 rpm, inertia scale 0.7-2.3)."""
    return {
        "sigma0": rng.uniform(-0.5, 0.5, (n, 3)),
        "omega0_rad_s": rng.uniform(-0.02, 0.02, (n, 3)),
        "wheel_speed0_rad_s": rng.uniform(-1000.0, 1000.0, (n, 4)) * RPM_TO_RAD_S,
        "inertia_scale": rng.uniform(0.7, 2.3, n),
        "fault": random_faults(rng, n) if faults else PlantFault.healthy(n),
        "environment": random_environment(rng, n),
    }


def random_sensor_episodes(rng: np.random.Generator, n: int, onset_step: np.ndarray) -> SensorEpisodes:
    """Healthy star trackers and gyro; a third of the magnetometers biased (1-15 uT), a third
    spiking (p 0.1, amount 2 on every axis), all from ``onset_step``."""
    kind = np.arange(n) % 3  # 0 healthy, 1 bias, 2 spike
    mag = MagnetometerFault(
        kind=np.where(kind == 1, MAG_BIAS, np.where(kind == 2, MAG_SPIKE, 0)),
        bias_t=rng.uniform(1e-6, 15e-6, n)[:, None] * unit_vectors(rng, n),
        spike_probability=np.where((kind == 2)[:, None], 0.1, 0.0) * np.ones((n, 3)),
        spike_amount=np.full((n, 3), 2.0),
    )
    none = SensorFault(
        np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64), np.zeros((n, 3)), np.zeros((n, 3))
    )
    seeds = rng.integers(0, 2**32, size=(n, 4), dtype=np.uint32)
    return SensorEpisodes(
        np.asarray(onset_step, dtype=np.int64), none, mag, seeds, np.zeros(n, dtype=np.int64)
    )
