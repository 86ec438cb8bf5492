"""``scftc-v1``'s fault taxonomy: the only code that draws its faults and initial conditions.

Pinned draws (``draw_episodes``) take every random number from a ``SeedSequence`` keyed by the
benchmark version, split, class and index (``sim/episodes.py``), so every controller meets the
identical episodes of a cell and two controllers can be compared pair by pair; a sealed draw mixes
a ``salt`` into the key: same distribution, episodes nobody can regenerate without the salt.
``sample_episodes`` draws fresh random episodes from a caller's generator, for training.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.sim.episodes import Episodes, generator
from scftc_cli.sim.mrp import from_axis_angle
from scftc_cli.spec import V1, BenchmarkSpec, RigidBodyPlant, RigidBodySplit


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
    split: RigidBodySplit, fault_class: str, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, float]:
    """Draw one fault ``(g (3,), b (3,), f)`` of ``fault_class`` from ``split``.

    The order of the draws is part of the benchmark: ``f``, the number of reversed axes, which
    axes, the magnitudes (``gain``, ``gain_bias``, ``loss``), the biases (``gain_bias``), the dead
    axis (``loss``).
    """
    f = float(split.inertia_scale.sample(rng, 1)[0])
    n_reversed = int(rng.choice(split.reversed_axes))
    sign = np.ones(3)
    sign[rng.choice(3, size=n_reversed, replace=False)] = -1.0
    gain = sign if fault_class == "sign" else sign * split.gain_magnitude.sample(rng, 3)
    bias = split.bias.sample(rng, 3) if fault_class == "gain_bias" else np.zeros(3)
    if fault_class == "loss":
        gain[rng.integers(3)] = 0.0
    return gain, bias, f


def sample_initial_state(plant: RigidBodyPlant, rng: np.random.Generator, n: int) -> tuple[np.ndarray, ...]:
    """``(sigma0, omega0)``, each ``(n, 3)``: uniform in ``[-0.5, 0.5]^3`` and ``[-0.02, 0.02]^3``
    rad/s (the spec's half widths), the attitudes drawn first."""
    sigma0 = rng.uniform(-plant.sigma0_half_width, plant.sigma0_half_width, (n, 3))
    omega0 = rng.uniform(-plant.omega0_half_width_rad_s, plant.omega0_half_width_rad_s, (n, 3))
    return sigma0, omega0


def unit_norm(v: np.ndarray) -> float:
    """``|v|`` of a 3-vector summed left to right: the same bits on every CPU (``np.linalg.norm``
    goes through BLAS, whose kernels differ in the last bit between CPUs, and a draw must not)."""
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def check_cell(spec: BenchmarkSpec, split: str, fault_class: str, sensor: str | None) -> None:
    """Raise ``UnknownNameError`` naming the valid choices if the cell does not exist."""
    if split not in spec.splits:
        raise UnknownNameError("split", split, spec.splits)
    if fault_class not in spec.fault_classes:
        raise UnknownNameError("fault class", fault_class, spec.fault_classes)
    if sensor is not None:
        if sensor not in spec.sensor_faults:
            raise UnknownNameError("sensor fault", sensor, spec.sensor_faults)
        if fault_class != spec.sensor_base_class:
            raise UsageError(f"sensor faults are defined on top of `{spec.sensor_base_class}` faults")


@functools.lru_cache(maxsize=64)
def draw_episodes(
    split: str,
    fault_class: str,
    sensor: str | None = None,
    n_faults: int = V1.n_faults,
    n_seeds: int = V1.n_seeds,
    salt: bytes = b"",
) -> RigidEpisodes:
    """The pinned (or, with ``salt``, sealed) episodes of a cell: ``n_faults`` faults x
    ``n_seeds`` initial conditions, fault-major.

    Sensor faults sit on top of the split's ``sign`` faults, with the very same faults and initial
    conditions as the ``sign`` cell, so the two cells pair episode by episode. A pure function of
    its arguments, so it is cached (every controller of a battery meets the same cells); the
    arrays of the returned episodes are read-only (shared between callers).
    """
    spec = V1
    check_cell(spec, split, fault_class, sensor)
    key = (split, fault_class)
    gains, biases, scales = [], [], []
    for i in range(n_faults):
        g, b, f = sample_fault(
            spec.splits[split], fault_class, generator(spec.version, *key, index=(0, i), salt=salt)
        )
        gains.append(g)
        biases.append(b)
        scales.append(f)
    n = n_faults * n_seeds
    sigma0, omega0, bias_axis = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for i in range(n_faults):
        for j in range(n_seeds):
            e = i * n_seeds + j
            rng = generator(spec.version, *key, index=(1, i, j), salt=salt)
            (sigma0[e],), (omega0[e],) = sample_initial_state(spec.plant, rng, 1)
            if sensor is not None:
                v = generator(spec.version, *key, "attitude_bias", index=(i, j), salt=salt).standard_normal(3)
                bias_axis[e] = v / unit_norm(v)
    sensor_bias = None
    if sensor is not None and sensor.startswith("bias_"):
        sensor_bias = from_axis_angle(bias_axis, np.radians(float(sensor.removeprefix("bias_"))))
    rep = lambda x: np.repeat(np.asarray(x, dtype=float), n_seeds, axis=0)  # noqa: E731
    return RigidEpisodes(
        benchmark=spec.version,
        split=split,
        fault_class=fault_class,
        sensor=sensor,
        fault_index=np.repeat(np.arange(n_faults), n_seeds),
        seed_index=np.tile(np.arange(n_seeds), n_faults),
        fault=ActuatorFault(rep(gains), rep(biases), rep(scales)),
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
        check_cell(spec, split, c, None)
    if not classes:
        raise UsageError("name at least one fault class")
    gains, biases, scales = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
    for e in range(n):
        gains[e], biases[e], scales[e] = sample_fault(
            spec.splits[split], classes[rng.integers(len(classes))], rng
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
