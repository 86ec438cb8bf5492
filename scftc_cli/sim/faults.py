"""The fault taxonomy: the only code that draws faults and initial conditions (SPEC sections 2-3).

Every random number here comes from a ``numpy.random.SeedSequence`` keyed by the benchmark
version, split, class and index, so every controller meets the identical episodes of a cell
and two controllers can be compared pair by pair. A private draw (leaderboard) mixes a secret
``salt`` into the key: same distribution, episodes nobody can regenerate from the open code.
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass

import numpy as np

from scftc_cli import BENCHMARK_VERSION
from scftc_cli.errors import UnknownNameError
from scftc_cli.sim.mrp import from_axis_angle
from scftc_cli.spec import SPEC, SplitSpec


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
class Episodes:
    """Everything that defines the episodes of one cell; held by the simulator, never by a
    deployable controller.

    Attributes:
        split, fault_class, sensor: the cell (``sensor`` is ``None`` for actuator-only cells).
        fault: per-episode actuator faults (``n = n_faults * n_seeds``, fault-major order).
        sigma0, omega0_rad_s: ``(n, 3)`` initial true attitude (MRP) and body rate.
        sensor_bias_mrp: ``(n, 3)`` constant attitude-measurement offset, or ``None``.
        fault_index, seed_index: ``(n,)`` which fault and which initial-condition seed.
    """

    split: str
    fault_class: str
    sensor: str | None
    fault: ActuatorFault
    sigma0: np.ndarray
    omega0_rad_s: np.ndarray
    sensor_bias_mrp: np.ndarray | None
    fault_index: np.ndarray
    seed_index: np.ndarray

    @property
    def n(self) -> int:
        return len(self.sigma0)

    def subset(self, idx: np.ndarray | slice) -> Episodes:
        """The episodes at ``idx`` (used to cross-check a few episodes on Basilisk)."""
        pick = lambda x: None if x is None else x[idx]  # noqa: E731
        return Episodes(
            self.split,
            self.fault_class,
            self.sensor,
            ActuatorFault(self.fault.gain[idx], self.fault.bias[idx], self.fault.inertia_scale[idx]),
            self.sigma0[idx],
            self.omega0_rad_s[idx],
            pick(self.sensor_bias_mrp),
            self.fault_index[idx],
            self.seed_index[idx],
        )


def seed_sequence(*key: str, index: tuple[int, ...], salt: bytes = b"") -> np.random.SeedSequence:
    """A ``SeedSequence`` keyed by benchmark version, the names in ``key`` and ``index``."""
    digest = hashlib.sha256("|".join((BENCHMARK_VERSION, *key)).encode() + salt).digest()
    return np.random.SeedSequence(int.from_bytes(digest[:16], "little"), spawn_key=index)


def sample_fault(
    split: SplitSpec, fault_class: str, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, float]:
    """Draw one fault ``(g (3,), b (3,), f)`` of ``fault_class`` from ``split`` (SPEC section 2)."""
    f = float(split.inertia_scale.sample(rng, 1)[0])
    n_reversed = int(rng.choice(split.reversed_axes))
    sign = np.ones(3)
    sign[rng.choice(3, size=n_reversed, replace=False)] = -1.0
    gain = sign if fault_class == "sign" else sign * split.gain_magnitude.sample(rng, 3)
    bias = split.bias.sample(rng, 3) if fault_class == "gain_bias" else np.zeros(3)
    if fault_class == "loss":
        gain[rng.integers(3)] = 0.0
    return gain, bias, f


def _check_names(split: str, fault_class: str, sensor: str | None) -> None:
    if split not in SPEC.splits:
        raise UnknownNameError("split", split, SPEC.splits)
    if fault_class not in SPEC.fault_classes:
        raise UnknownNameError("fault class", fault_class, SPEC.fault_classes)
    if sensor is not None and sensor not in SPEC.sensor_faults:
        raise UnknownNameError("sensor fault", sensor, SPEC.sensor_faults)


@functools.lru_cache(maxsize=64)
def draw_episodes(
    split: str,
    fault_class: str,
    sensor: str | None = None,
    n_faults: int = SPEC.n_faults,
    n_seeds: int = SPEC.n_seeds,
    salt: bytes = b"",
) -> Episodes:
    """The pinned episodes of a cell: ``n_faults`` faults x ``n_seeds`` initial conditions.

    Sensor faults sit on top of the split's ``sign`` faults (SPEC section 2), with the very same
    faults and initial conditions as the ``sign`` cell, so the two cells pair episode by episode.
    The first ``k`` faults and seeds of a cell do not depend on ``n_faults`` or ``n_seeds``.

    A pure function of its arguments, so it is cached: every controller of a battery meets the
    same cells, and drawing one costs a third of flying ``pd`` through it. The arrays of the
    returned episodes are read-only (shared between callers).
    """
    _check_names(split, fault_class, sensor)
    if sensor is not None and fault_class != "sign":
        raise UnknownNameError("fault class for sensor faults", fault_class, ("sign",))
    split_spec, plant = SPEC.splits[split], SPEC.plant
    gains, biases, scales = [], [], []
    for i in range(n_faults):
        rng = np.random.default_rng(seed_sequence(split, fault_class, index=(0, i), salt=salt))
        g, b, f = sample_fault(split_spec, fault_class, rng)
        gains.append(g), biases.append(b), scales.append(f)
    sigma0 = np.empty((n_faults * n_seeds, 3))
    omega0 = np.empty((n_faults * n_seeds, 3))
    bias_axis = np.empty((n_faults * n_seeds, 3))
    for i in range(n_faults):
        for j in range(n_seeds):
            e = i * n_seeds + j
            rng = np.random.default_rng(seed_sequence(split, fault_class, index=(1, i, j), salt=salt))
            sigma0[e] = rng.uniform(-plant.sigma0_half_width, plant.sigma0_half_width, 3)
            omega0[e] = rng.uniform(-plant.omega0_half_width_rad_s, plant.omega0_half_width_rad_s, 3)
            if sensor is not None:
                rng = np.random.default_rng(
                    seed_sequence(split, fault_class, "attitude_bias", index=(i, j), salt=salt)
                )
                v = rng.standard_normal(3)
                bias_axis[e] = v / np.linalg.norm(v)
    sensor_bias = None
    if sensor is not None and sensor.startswith("bias_"):
        sensor_bias = from_axis_angle(bias_axis, np.radians(float(sensor.removeprefix("bias_"))))
    rep = lambda x: np.repeat(np.asarray(x, dtype=float), n_seeds, axis=0)  # noqa: E731
    arrays = (
        rep(gains),
        rep(biases),
        rep(scales),
        sigma0,
        omega0,
        sensor_bias,
        np.repeat(np.arange(n_faults), n_seeds),
        np.tile(np.arange(n_seeds), n_faults),
    )
    for array in arrays:
        if array is not None:
            array.flags.writeable = False
    gain, bias, scale, sigma0, omega0, sensor_bias, fault_index, seed_index = arrays
    return Episodes(
        split=split,
        fault_class=fault_class,
        sensor=sensor,
        fault=ActuatorFault(gain, bias, scale),
        sigma0=sigma0,
        omega0_rad_s=omega0,
        sensor_bias_mrp=sensor_bias,
        fault_index=fault_index,
        seed_index=seed_index,
    )
