"""``scftc-v2``'s fault taxonomy: the only code that draws its faults, initial states and noise seeds.

Every actuator fault acts per wheel and starts at an onset time ``t_f`` (healthy before it); the
sensor faults sit on top of the split's ``sign`` faults, start at the same onset, and share the
``sign`` cell's faults, initial states *and* sensor-noise streams, so the two cells pair episode by
episode. Pinned draws key every random number (faults, initial states, sensor faults and each
episode's noise stream) by the benchmark version, split, class and index (``sim/episodes.py``); a
sealed draw mixes a ``salt`` into the key. The order of the draws below is part of the benchmark.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from scftc_cli.errors import UsageError
from scftc_cli.sim.elementary import tangent
from scftc_cli.sim.episodes import Episodes, generator, seed_sequence, unit_norm
from scftc_cli.spec import BenchmarkSpec, FaultClass
from scftc_cli.versions.v2.sim.dynamics import RPM_TO_RAD_S
from scftc_cli.versions.v2.spec import V2, ReactionWheelPlant, WheelSplit


@dataclass(frozen=True)
class WheelFault:
    """Per-episode actuator fault of ``m`` wheels, in force from ``onset_step`` on.

    Attributes:
        gain: ``(n, m)`` effectiveness ``g_i`` (negative reversed, 0 dead; 1 healthy).
        bias: ``(n, m)`` offset ``b_i``, a fraction of ``u_max``.
        friction_multiplier: ``(n, m)`` Coulomb friction as a multiple of ``fC0`` (1 healthy).
        inertia_scale: ``(n,)`` hub inertia scale ``f`` (a mass property: present from step 0).
        onset_step: ``(n,)`` first faulted step: the first ``k`` with ``k dt >= t_f``.
    """

    gain: np.ndarray
    bias: np.ndarray
    friction_multiplier: np.ndarray
    inertia_scale: np.ndarray
    onset_step: np.ndarray

    def healthy_actuators(self) -> np.ndarray:
        """``(n, m)`` bool: the wheels the fault leaves as a healthy wheel (gain 1, no offset,
        nominal friction)."""
        return (
            (np.asarray(self.gain) == 1.0)
            & (np.asarray(self.bias) == 0.0)
            & (np.asarray(self.friction_multiplier) == 1.0)
        )

    def at(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(gain, bias, friction_multiplier)`` ``(n, m)`` in force during step ``k``."""
        active = (k >= self.onset_step)[:, None]
        return (
            np.where(active, self.gain, 1.0),
            np.where(active, self.bias, 0.0),
            np.where(active, self.friction_multiplier, 1.0),
        )


@dataclass(frozen=True)
class SensorFault:
    """Per-episode sensor fault.

    Attributes:
        kind: ``(n,)`` which sensor fault: 0 none, else 1 + its index in the spec's
            ``sensor_faults`` (``sensor_code``); one batch may mix them (training).
        head: ``(n,)`` the faulted star-tracker head (``st_bias``, ``st_stuck``).
        head_bias_mrp: ``(n, 3)`` the head's constant rotation offset (``st_bias``; zeros otherwise).
        gyro_bias_step_rad_s: ``(n, 3)`` the gyro-bias step (``gyro_bias``; zeros otherwise).
    """

    kind: np.ndarray
    head: np.ndarray
    head_bias_mrp: np.ndarray
    gyro_bias_step_rad_s: np.ndarray


def sensor_code(spec: BenchmarkSpec, sensor: str | None) -> int:
    """``SensorFault.kind`` of ``sensor``: 0 for healthy sensors, else 1 + its place in the spec."""
    return 0 if sensor is None else 1 + spec.sensor_faults.index(sensor)


@dataclass(frozen=True)
class WheelEpisodes(Episodes):
    """Everything that defines a batch of ``scftc-v2`` episodes; held by the simulator, never by a
    deployable controller.

    Attributes:
        fault: per-episode actuator faults.
        sigma0, omega0_rad_s: ``(n, 3)`` initial true attitude (MRP) and body rate.
        wheel_speed0_rad_s: ``(n, m)`` initial wheel speeds.
        sensor_fault: per-episode sensor-fault parameters.
        noise_seed: ``(n, 4)`` ``uint32``: the entropy of each episode's sensor-noise stream.
    """

    fault: WheelFault
    sigma0: np.ndarray
    omega0_rad_s: np.ndarray
    wheel_speed0_rad_s: np.ndarray
    sensor_fault: SensorFault
    noise_seed: np.ndarray


def onset_step(onset_s: np.ndarray, dt_s: float) -> np.ndarray:
    """The first step ``k`` with ``k dt >= t_f``, ``(n,)`` int (exact: ``dt`` is a power of two here)."""
    k = np.ceil(np.asarray(onset_s) / dt_s).astype(np.int64)
    return np.where((k - 1) * dt_s >= onset_s, k - 1, k)


def sample_fault(split: WheelSplit, fault_class: FaultClass, m: int, rng: np.random.Generator) -> tuple:
    """Draw one fault ``(g (m,), b (m,), friction multiplier (m,), f, t_f)`` of ``fault_class``.

    The order of the draws is part of the benchmark: ``f``, ``t_f``, the number of reversed wheels,
    which wheels, the magnitudes (a class with ``magnitude``), the offsets (``bias``), the friction
    wheel and its multiplier (``friction``), the dead wheel (``dead``).
    """
    f = float(split.inertia_scale.sample(rng, 1)[0])
    t_f = float(split.onset_s.sample(rng, 1)[0])
    n_reversed = int(rng.choice(split.reversed_wheels))
    sign = np.ones(m)
    sign[rng.choice(m, size=n_reversed, replace=False)] = -1.0
    gain = sign * split.gain_magnitude.sample(rng, m) if fault_class.magnitude else sign
    bias = split.bias.sample(rng, m) if fault_class.bias else np.zeros(m)
    friction = np.ones(m)
    if fault_class.friction:
        wheel = int(rng.integers(m))
        friction[wheel] = float(split.friction_multiplier.sample(rng, 1)[0])
    if fault_class.dead:
        gain[rng.integers(m)] = 0.0
    return gain, bias, friction, f, t_f


def sample_initial_state(
    plant: ReactionWheelPlant, rng: np.random.Generator, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(sigma0 (n, 3), omega0 (n, 3), wheel_speed0 (n, m))``: attitudes and rates as v1, then
    wheel speeds uniform in +- ``wheel_speed0_half_width_rpm``."""
    sigma0 = rng.uniform(-plant.sigma0_half_width, plant.sigma0_half_width, (n, 3))
    omega0 = rng.uniform(-plant.omega0_half_width_rad_s, plant.omega0_half_width_rad_s, (n, 3))
    half = plant.wheel_speed0_half_width_rpm * RPM_TO_RAD_S
    wheels = rng.uniform(-half, half, (n, plant.n_wheels))
    return sigma0, omega0, wheels


def head_bias_mrp(axis: np.ndarray, angle_deg: float) -> np.ndarray:
    """MRP ``tan(angle/4) axis`` of a rotation about unit ``axis`` (3,), with the project's
    correctly rounded ``tan`` (``sim/elementary``: the same bits on every CPU and libm)."""
    return float(tangent(math.radians(angle_deg) / 4.0)) * axis


def sample_sensor_fault(
    split: WheelSplit, sensor: str | None, heads: int, rng: np.random.Generator
) -> tuple[int, np.ndarray, np.ndarray]:
    """One episode's sensor fault ``(head, head bias MRP (3,), gyro-bias step (3,) rad/s)``.

    ``st_bias``: the head, a uniform axis, the angle; ``st_stuck``: the head; ``gyro_bias``: the
    size per axis, then the signs; ``st_outage`` and healthy cells draw nothing.
    """
    head, bias, step = 0, np.zeros(3), np.zeros(3)
    if sensor in ("st_bias", "st_stuck"):
        head = int(rng.integers(heads))
    if sensor == "st_bias":
        v = rng.standard_normal(3)
        axis = v / unit_norm(v)
        bias = head_bias_mrp(axis, float(split.head_bias_deg.sample(rng, 1)[0]))
    if sensor == "gyro_bias":
        size = np.radians(split.gyro_bias_step_deg_s.sample(rng, 3))
        step = size * np.where(rng.random(3) < 0.5, -1.0, 1.0)
    return head, bias, step


def _split(spec: BenchmarkSpec, split: str) -> WheelSplit:
    ranges = spec.splits[split]
    assert isinstance(ranges, WheelSplit)
    return ranges


def _plant(spec: BenchmarkSpec) -> ReactionWheelPlant:
    assert isinstance(spec.plant, ReactionWheelPlant)
    return spec.plant


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
) -> WheelEpisodes:
    """Episodes ``start..stop-1`` of the pinned (or, with ``salt``, sealed) cell of ``n_faults``
    faults x ``n_seeds`` initial conditions, fault-major (``Testbed.draw`` checks the arguments),
    drawn without drawing the others (equal to that slice of the whole cell).

    Keys: the fault ``(split, class)`` index ``(0, i)``; the initial state index ``(1, i, j)``; the
    sensor fault ``(split, class, "sensor", sensor)`` index ``(i, j)``; the noise stream
    ``(split, class, "noise")`` index ``(i, j)``: the same for a sensor cell as for its ``sign``
    cell. Cached (a pure function); the returned arrays are read-only.
    """
    spec = V2
    ranges, plant = _split(spec, split), _plant(spec)
    heads = spec.sensors.star_tracker_heads if spec.sensors else 0
    m = plant.n_wheels
    key = (split, fault_class)
    kind = spec.fault_class(fault_class)
    first_fault, last_fault = start // n_seeds, (stop - 1) // n_seeds
    faults = {
        i: sample_fault(ranges, kind, m, generator(spec.version, *key, index=(0, i), salt=salt))
        for i in range(first_fault, last_fault + 1)
    }
    rows = stop - start
    gain, bias, friction = np.empty((rows, m)), np.empty((rows, m)), np.empty((rows, m))
    scale, onset_s = np.empty(rows), np.empty(rows)
    sigma0, omega0, wheels0 = np.empty((rows, 3)), np.empty((rows, 3)), np.empty((rows, m))
    head, head_bias, gyro_step = np.zeros(rows, dtype=np.int64), np.zeros((rows, 3)), np.zeros((rows, 3))
    noise_seed = np.empty((rows, 4), dtype=np.uint32)
    fault_index, seed_index = np.empty(rows, dtype=np.int64), np.empty(rows, dtype=np.int64)
    for row, e in enumerate(range(start, stop)):
        i, j = divmod(e, n_seeds)
        gain[row], bias[row], friction[row], scale[row], onset_s[row] = faults[i]
        fault_index[row], seed_index[row] = i, j
        rng = generator(spec.version, *key, index=(1, i, j), salt=salt)
        (sigma0[row],), (omega0[row],), (wheels0[row],) = sample_initial_state(plant, rng, 1)
        if sensor is not None:
            rng = generator(spec.version, *key, "sensor", sensor, index=(i, j), salt=salt)
            head[row], head_bias[row], gyro_step[row] = sample_sensor_fault(ranges, sensor, heads, rng)
        noise = seed_sequence(spec.version, *key, "noise", index=(i, j), salt=salt)
        noise_seed[row] = noise.generate_state(4, np.uint32)
    return WheelEpisodes(
        benchmark=spec.version,
        split=split,
        fault_class=fault_class,
        sensor=sensor,
        fault_index=fault_index,
        seed_index=seed_index,
        fault=WheelFault(gain, bias, friction, scale, onset_step(onset_s, plant.dt_s)),
        sigma0=sigma0,
        omega0_rad_s=omega0,
        wheel_speed0_rad_s=wheels0,
        sensor_fault=SensorFault(
            np.full(rows, sensor_code(spec, sensor), dtype=np.int64), head, head_bias, gyro_step
        ),
        noise_seed=noise_seed,
    ).readonly()


def sample_episodes_batch(
    rng: np.random.Generator,
    n: int,
    split: str,
    classes: tuple[str, ...],
    sensors: tuple[str | None, ...] = (None,),
    spec: BenchmarkSpec = V2,
) -> WheelEpisodes:
    """``n`` fresh random episodes of ``split`` for training and the gymnasium environment, drawn
    as whole arrays from ``rng``: each of an actuator class uniform over ``classes`` and a sensor
    class uniform over ``sensors`` (``None``: healthy sensors; a sensor fault turns its episode's
    actuator fault into a ``sign`` fault, as in the benchmark's sensor cells). The distribution of
    every parameter is the pinned draws' (``tests/versions/v2/sim/test_faults.py`` checks it); the random
    stream is not.
    """
    if not classes or not sensors:
        raise UsageError("name at least one fault class and one sensor class (None: healthy)")
    for c in classes:
        spec.check_cell(split, c)
    for s in sensors:
        if s is not None:
            spec.check_cell(split, spec.sensor_base_class, s)
    ranges, plant = _split(spec, split), _plant(spec)
    m = plant.n_wheels
    heads = spec.sensors.star_tracker_heads if spec.sensors else 0
    sensor_index = rng.integers(len(sensors), size=n)
    sensor = np.asarray([s or "" for s in sensors])[sensor_index]
    cls = np.where(
        sensor != "", spec.sensor_base_class, np.asarray(classes)[rng.integers(len(classes), size=n)]
    )
    names, which = np.unique(cls, return_inverse=True)
    kinds = [spec.fault_class(str(c)) for c in names]
    draws = {
        flag: np.array([getattr(k, flag) for k in kinds], dtype=bool)[which.reshape(n)]
        for flag in ("magnitude", "bias", "friction", "dead")
    }
    scale = ranges.inertia_scale.sample(rng, n)
    onset_s = ranges.onset_s.sample(rng, n)
    n_reversed = rng.choice(np.asarray(ranges.reversed_wheels), size=n)
    ranks = np.argsort(rng.random((n, m)), axis=1).argsort(axis=1)  # a uniform random order of wheels
    sign = np.where(ranks < n_reversed[:, None], -1.0, 1.0)
    magnitude = np.where(draws["magnitude"][:, None], ranges.gain_magnitude.sample(rng, (n, m)), 1.0)
    gain = sign * magnitude
    bias = np.where(draws["bias"][:, None], ranges.bias.sample(rng, (n, m)), 0.0)
    friction = np.ones((n, m))
    rows = np.flatnonzero(draws["friction"])
    friction[rows, rng.integers(m, size=n)[rows]] = ranges.friction_multiplier.sample(rng, n)[rows]
    rows = np.flatnonzero(draws["dead"])
    gain[rows, rng.integers(m, size=n)[rows]] = 0.0
    sigma0, omega0, wheels0 = sample_initial_state(plant, rng, n)
    head = rng.integers(max(heads, 1), size=n)
    v = rng.standard_normal((n, 3))
    axis = v / np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])[:, None]
    angle = np.radians(ranges.head_bias_deg.sample(rng, n))
    head_bias = np.where((sensor == "st_bias")[:, None], tangent(angle / 4.0)[:, None] * axis, 0.0)
    size = np.radians(ranges.gyro_bias_step_deg_s.sample(rng, (n, 3)))
    step = np.where(
        (sensor == "gyro_bias")[:, None], size * np.where(rng.random((n, 3)) < 0.5, -1.0, 1.0), 0.0
    )
    labels = sorted(set(cls.tolist()) | {s for s in sensor.tolist() if s})
    return WheelEpisodes(
        benchmark=spec.version,
        split=split,
        fault_class="mixed" if len(labels) > 1 else labels[0],
        sensor=None,
        fault_index=np.arange(n),
        seed_index=np.zeros(n, dtype=np.int64),
        fault=WheelFault(gain, bias, friction, scale, onset_step(onset_s, plant.dt_s)),
        sigma0=sigma0,
        omega0_rad_s=omega0,
        wheel_speed0_rad_s=wheels0,
        sensor_fault=SensorFault(
            np.asarray([sensor_code(spec, s) for s in sensors])[sensor_index], head, head_bias, step
        ),
        noise_seed=rng.integers(0, 2**32, size=(n, 4), dtype=np.uint32),
    )
