"""``scftc-v1``'s fault taxonomy: the only code that draws its faults and initial conditions.

Pinned draws (``pinned_episodes``, through ``Testbed.draw``) take every random number from a
``SeedSequence`` keyed by the benchmark version, split, class and index (``sim/episodes.py``), so
every controller meets the identical episodes of a cell and two controllers can be compared pair
by pair; a sealed draw mixes a ``salt`` into the key: same distribution, episodes nobody can
regenerate without the salt.
``sample_episodes`` draws fresh random episodes from a caller's generator, for training.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from scftc_cli.errors import UsageError
from scftc_cli.sim.episodes import Episodes, generator, unit_norm
from scftc_cli.sim.mrp import from_axis_angle
from scftc_cli.spec import BenchmarkSpec, FaultClass
from scftc_cli.versions.v1.spec import V1, RigidBodyPlant, RigidBodySplit


@dataclass(frozen=True)
class ActuatorFault:
    """Per-episode actuator fault ``z = (g, b, f)``.

    Attributes:
        gain: ``(n, 3)`` per-axis effectiveness ``g`` (negative reversed, 0 dead).
        bias: ``(n, 3)`` per-axis additive torque bias ``b``, a fraction of ``tau_max``.
        inertia_scale: ``(n,)`` inertia scale ``f`` (``I = f I0``).
    """

    gain: np.ndarray
    bias: np.ndarray
    inertia_scale: np.ndarray

    @property
    def theta(self) -> np.ndarray:
        """``(n, 3)`` identifiable effective authority ``g / f``."""
        return self.gain / self.inertia_scale[:, None]

    @property
    def beta(self) -> np.ndarray:
        """``(n, 3)`` identifiable effective bias ``b / f``."""
        return self.bias / self.inertia_scale[:, None]


@dataclass(frozen=True)
class RigidEpisodes(Episodes):
    """Everything that defines a batch of ``scftc-v1`` episodes; held by the simulator, never by
    a deployable controller.

    Attributes:
        fault: per-episode actuator faults (``n = n_faults * n_seeds``, fault-major order).
        sigma0, omega0_rad_s: ``(n, 3)`` initial true attitude (MRP) and body rate.
        sensor_bias_mrp: ``(n, 3)`` constant attitude-measurement offset, or ``None``.
    """

    fault: ActuatorFault
    sigma0: np.ndarray
    omega0_rad_s: np.ndarray
    sensor_bias_mrp: np.ndarray | None = None


def sample_fault(
    split: RigidBodySplit, fault_class: FaultClass, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, float]:
    """Draw one fault ``(g (3,), b (3,), f)`` of ``fault_class`` from ``split``.

    The order of the draws is part of the benchmark: ``f``, the number of reversed axes, which
    axes, the magnitudes (a class with ``magnitude``), the biases (``bias``), the dead axis (``dead``).
    """
    f = float(split.inertia_scale.sample(rng, 1)[0])
    n_reversed = int(rng.choice(split.reversed_axes))
    sign = np.ones(3)
    sign[rng.choice(3, size=n_reversed, replace=False)] = -1.0
    gain = sign * split.gain_magnitude.sample(rng, 3) if fault_class.magnitude else sign
    bias = split.bias.sample(rng, 3) if fault_class.bias else np.zeros(3)
    if fault_class.dead:
        gain[rng.integers(3)] = 0.0
    return gain, bias, f


def sample_initial_state(plant: RigidBodyPlant, rng: np.random.Generator, n: int) -> tuple[np.ndarray, ...]:
    """``(sigma0, omega0)``, each ``(n, 3)``: uniform in ``[-0.5, 0.5]^3`` and ``[-0.02, 0.02]^3``
    rad/s (the spec's half widths), the attitudes drawn first."""
    sigma0 = rng.uniform(-plant.sigma0_half_width, plant.sigma0_half_width, (n, 3))
    omega0 = rng.uniform(-plant.omega0_half_width_rad_s, plant.omega0_half_width_rad_s, (n, 3))
    return sigma0, omega0


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
) -> RigidEpisodes:
    """Episodes ``start..stop-1`` of the pinned (or, with ``salt``, sealed) cell of ``n_faults``
    faults x ``n_seeds`` initial conditions, fault-major (``Testbed.draw`` checks the arguments),
    drawn without drawing the others (a cluster's chunk of a large cell).

    Every episode comes from its own keyed streams, so a slice is exactly the same numbers as that
    slice of the whole cell. Sensor faults sit on top of the split's ``sign`` faults, with the very
    same faults and initial conditions as the ``sign`` cell, so the two cells pair episode by
    episode. A pure function of its arguments, so it is cached (every controller of a battery meets
    the same cells); the arrays of the returned episodes are read-only (shared between callers).
    """
    spec = V1
    key = (split, fault_class)
    first_fault, last_fault = start // n_seeds, (stop - 1) // n_seeds
    kind = spec.fault_class(fault_class)
    faults = {
        i: sample_fault(spec.splits[split], kind, generator(spec.version, *key, index=(0, i), salt=salt))
        for i in range(first_fault, last_fault + 1)
    }
    m = stop - start
    gain, bias, scale = np.empty((m, 3)), np.empty((m, 3)), np.empty(m)
    sigma0, omega0, bias_axis = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))
    fault_index, seed_index = np.empty(m, dtype=int), np.empty(m, dtype=int)
    for row, e in enumerate(range(start, stop)):
        i, j = divmod(e, n_seeds)
        gain[row], bias[row], scale[row] = faults[i]
        fault_index[row], seed_index[row] = i, j
        rng = generator(spec.version, *key, index=(1, i, j), salt=salt)
        (sigma0[row],), (omega0[row],) = sample_initial_state(spec.plant, rng, 1)
        if sensor is not None:
            v = generator(spec.version, *key, "attitude_bias", index=(i, j), salt=salt).standard_normal(3)
            bias_axis[row] = v / unit_norm(v)
    sensor_bias = None
    if sensor is not None and spec.sensor_class(sensor).kind == "bias":
        angle_deg = spec.sensor_class(sensor).angle_deg
        assert angle_deg is not None, f"the attitude-bias fault {sensor} declares no angle"
        sensor_bias = from_axis_angle(bias_axis, np.radians(angle_deg))
    return RigidEpisodes(
        benchmark=spec.version,
        split=split,
        fault_class=fault_class,
        sensor=sensor,
        fault_index=fault_index,
        seed_index=seed_index,
        fault=ActuatorFault(gain, bias, scale),
        sigma0=sigma0,
        omega0_rad_s=omega0,
        sensor_bias_mrp=sensor_bias,
    ).readonly()


def sample_episodes(
    rng: np.random.Generator, n: int, split: str, classes: tuple[str, ...], spec: BenchmarkSpec = V1
) -> RigidEpisodes:
    """``n`` fresh random episodes of ``split`` (training and the gymnasium environment), each of a
    class drawn uniformly from ``classes``: per episode the class then its fault, then every
    initial state at once (``sample_initial_state``)."""
    for c in classes:
        spec.check_cell(split, c)
    if not classes:
        raise UsageError("name at least one fault class")
    gains, biases, scales = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
    for e in range(n):
        gains[e], biases[e], scales[e] = sample_fault(
            spec.splits[split], spec.fault_class(classes[rng.integers(len(classes))]), rng
        )
    sigma0, omega0 = sample_initial_state(spec.plant, rng, n)
    return RigidEpisodes(
        benchmark=spec.version,
        split=split,
        fault_class="mixed",
        sensor=None,
        fault_index=np.arange(n),
        seed_index=np.zeros(n, dtype=int),
        fault=ActuatorFault(gains, biases, scales),
        sigma0=sigma0,
        omega0_rad_s=omega0,
    )


def sample_episodes_batch(
    rng: np.random.Generator, n: int, split: str, classes: tuple[str, ...], spec: BenchmarkSpec = V1
) -> RigidEpisodes:
    """``n`` fresh random episodes like ``sample_episodes`` (the same distribution, rule for rule),
    drawn as whole arrays: ~100x faster for large batches (the vector environment's reset), but a
    different random stream, so trainers that must regenerate committed weights bit for bit keep
    ``sample_episodes``. ``tests/versions/v1/sim/test_faults.py`` checks the two distributions agree."""
    if not classes:
        raise UsageError("name at least one fault class")
    for c in classes:
        spec.check_cell(split, c)
    ranges = spec.splits[split]
    kinds = [spec.fault_class(c) for c in classes]
    which = rng.integers(len(classes), size=n)
    draws = {
        flag: np.array([getattr(k, flag) for k in kinds])[which] for flag in ("magnitude", "bias", "dead")
    }
    scale = ranges.inertia_scale.sample(rng, n)
    n_reversed = rng.choice(np.asarray(ranges.reversed_axes), size=n)
    ranks = np.argsort(rng.random((n, 3)), axis=1).argsort(axis=1)  # a uniform random order of the axes
    sign = np.where(ranks < n_reversed[:, None], -1.0, 1.0)  # the first n_reversed of that order flip
    magnitude = np.where(draws["magnitude"][:, None], ranges.gain_magnitude.sample(rng, (n, 3)), 1.0)
    gain = sign * magnitude
    bias = np.where(draws["bias"][:, None], ranges.bias.sample(rng, (n, 3)), 0.0)
    dead = rng.integers(3, size=n)
    loss = draws["dead"]
    gain[np.flatnonzero(loss), dead[loss]] = 0.0
    sigma0, omega0 = sample_initial_state(spec.plant, rng, n)
    return RigidEpisodes(
        benchmark=spec.version,
        split=split,
        fault_class="mixed",
        sensor=None,
        fault_index=np.arange(n),
        seed_index=np.zeros(n, dtype=int),
        fault=ActuatorFault(gain, bias, scale),
        sigma0=sigma0,
        omega0_rad_s=omega0,
    )
