"""scftc-v3's sensors: v2's three star-tracker heads, gyro and tachometers, plus a magnetometer.

The v2 part is v2's own code (``HeadsGyroTachometers``) on v2's noise stream: for the same
episode seed its 19 values are exactly what v2 would observe of the same true state. The
magnetometer reads the true field in the body frame (``field_b_t`` of the plant: the field at the
current position, rotated with the current attitude) in tesla, with white noise of
``MAGNETOMETER_NOISE_T`` per axis, and two faults from the episode's onset on:

- ``mag_bias``: a constant vector added to every reading;
- ``mag_spike``: Basilisk's ``magnetometer`` spiking fault: each step, on each faulted axis, with
  probability ``p`` the reading (noise and bias included) is multiplied by ``amount``
  (Basilisk's ``spikeProbability``, default 0.1, and ``spikeAmount``, default 2).

One star-tracker fault differs from v2's: an ``st_outage`` ends. Every head reads zeros with
validity 0 from the onset to the episode's ``outage_end_step``, then reports again (v2's outage
lasts to the end). v2's code reads the heads as healthy and this class blanks them over the
outage, exactly as v2 blanks an outage (zeros, flag 0.0); the noise streams do not notice.

Each magnetometer gets its own streams, spawned from the episode's noise seed (spawn key ``(1,)``
for its normals, ``(2,)`` for the spike draws), so the v2 stream (spawn key ``()``) is untouched
and a faulted cell pairs with its healthy one episode by episode. Each step draws three normals
of every episode and three spike uniforms of every spiking one (none for the others).
The magnetometer does not see the rods' own field (a flight magnetometer would sit on a boom or
sample between torquing pulses).

``observe`` runs v2's fused kernel and a small numba pass for the magnetometer that draws its
noise and spikes itself (``sim/pcg64.py``: the numbers numpy's generators give);
tests/oracles/v3_sensors.py holds a readable numpy form, the same operations in the same order:
equal to the bit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numba
import numpy as np

from scftc_cli.sim.pcg64 import next_double, seeded_states, standard_normal
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, run_rows
from scftc_cli.sim.testbed import Plant, Sensors
from scftc_cli.versions.v2.sim.faults import SensorFault, sensor_code
from scftc_cli.versions.v2.sim.sensors import HeadsGyroTachometers
from scftc_cli.versions.v2.spec import V2

MAGNETOMETER_NOISE_T = 50e-9
"""White noise per axis per sample, 1 sigma (a fluxgate or good AMR magnetometer, ~50 nT)."""
MAG_CHANNELS = 3
MAG_NONE, MAG_BIAS, MAG_SPIKE = 0, 1, 2


@dataclass(frozen=True)
class MagnetometerFault:
    """Per-episode magnetometer fault, in force from the episode's onset step on.

    Attributes:
        kind: ``(n,)`` int: ``MAG_NONE``, ``MAG_BIAS`` or ``MAG_SPIKE``.
        bias_t: ``(n, 3)`` the constant bias, body axes, tesla (``mag_bias``).
        spike_probability: ``(n, 3)`` per-axis probability of a spike each step (``mag_spike``;
            0 on axes without the fault).
        spike_amount: ``(n, 3)`` what a spike multiplies the reading by.
    """

    kind: np.ndarray
    bias_t: np.ndarray
    spike_probability: np.ndarray
    spike_amount: np.ndarray

    @classmethod
    def healthy(cls, n: int) -> MagnetometerFault:
        return cls(np.zeros(n, dtype=np.int64), np.zeros((n, 3)), np.zeros((n, 3)), np.ones((n, 3)))


@dataclass(frozen=True)
class _Onset:
    onset_step: np.ndarray


@dataclass(frozen=True)
class SensorEpisodes:
    """What the sensors of a batch need of its episodes (the shape of v2's ``WheelEpisodes`` that
    ``HeadsGyroTachometers`` reads, plus the magnetometer's fault).

    Attributes:
        onset_step: ``(n,)`` int, the first faulted step (sensor faults share the actuators').
        sensor_fault: v2's star-tracker and gyro faults (kinds coded as in v2).
        magnetometer: The magnetometer's fault.
        noise_seed: ``(n, 4)`` uint32, the entropy of each episode's sensor-noise streams.
        outage_end_step: ``(n,)`` int, the first step an ``st_outage``'s heads are back (unread
            where the episode has no outage).
    """

    onset_step: np.ndarray
    sensor_fault: SensorFault
    magnetometer: MagnetometerFault
    noise_seed: np.ndarray
    outage_end_step: np.ndarray

    @property
    def n(self) -> int:
        return len(self.onset_step)

    @property
    def fault(self) -> _Onset:
        """v2's ``episodes.fault``, as far as its sensors read it."""
        return _Onset(np.asarray(self.onset_step))

    @classmethod
    def healthy(cls, noise_seed: np.ndarray) -> SensorEpisodes:
        """Healthy sensors for episodes with these seeds ``(n, 4)``."""
        n = len(noise_seed)
        fault = SensorFault(
            np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64), np.zeros((n, 3)), np.zeros((n, 3))
        )
        return cls(
            np.zeros(n, dtype=np.int64), fault, MagnetometerFault.healthy(n), np.asarray(noise_seed),
            np.zeros(n, dtype=np.int64),
        )  # fmt: skip


NORMALS_KEY, SPIKES_KEY = 1, 2
"""Spawn keys of the magnetometer's two streams (v2's stream has none)."""


class V3Sensors(Sensors):
    """The sensors of a batch of v3 episodes. Observation ``(n, 22)``: v2's 19 values (three head
    MRPs, three validity flags, gyro rad/s, tachometers rad/s), then the magnetometer (3) tesla."""

    def __init__(self, episodes: SensorEpisodes, noise_t: float = MAGNETOMETER_NOISE_T) -> None:
        fault = episodes.sensor_fault
        kind = np.asarray(fault.kind)
        self.outage = np.ascontiguousarray(kind == sensor_code(V2, "st_outage"))
        self.outage_end = np.ascontiguousarray(episodes.outage_end_step, dtype=np.int64)
        v2_view = dataclasses.replace(  # v2's code sees the heads healthy; ``_blank`` makes the outage
            episodes, sensor_fault=dataclasses.replace(fault, kind=np.where(self.outage, 0, kind))
        )
        self.v2 = HeadsGyroTachometers(v2_view, V2)  # type: ignore[arg-type]
        self.noise_t = noise_t
        mag = episodes.magnetometer
        # own copies: writable whatever the episodes' arrays are (the kernel is compiled once)
        self.onset = np.array(episodes.onset_step, dtype=np.int64)
        self.biased = np.ascontiguousarray(np.asarray(mag.kind) == MAG_BIAS)
        self.spiking = np.ascontiguousarray(np.asarray(mag.kind) == MAG_SPIKE)
        self.bias_t = np.array(mag.bias_t, dtype=np.float64)
        self.spike_probability = np.array(mag.spike_probability, dtype=np.float64)
        self.spike_amount = np.array(mag.spike_amount, dtype=np.float64)
        self.noise_seed = np.ascontiguousarray(episodes.noise_seed, dtype=np.uint32)
        self.rng = seeded_states(self.noise_seed, (NORMALS_KEY,))  # observe's copies of the streams
        self.spike_rng = seeded_states(self.noise_seed, (SPIKES_KEY,))  # read only where spiking
        self.next_step = 0  # the step observe reads next

    def _blank(self, k: int, head: np.ndarray) -> np.ndarray:
        """``head`` ``(n, 19)`` with every head zero and invalid where an outage is in force at
        step ``k`` (in place)."""
        out = np.flatnonzero(self.outage & (self.onset <= k) & (k < self.outage_end))
        head[out, : 4 * self.v2.heads] = 0.0  # each head's MRP (3 values), then each one's flag
        return head

    def observe(self, k: int, plant: Plant) -> np.ndarray:
        """``(n, 22)`` observation of the plant's true state at the start of step ``k`` (steps are
        read in order, each once)."""
        if k != self.next_step:
            raise ValueError(f"sensors are read step by step; step {k} follows {self.next_step - 1}")
        head = self._blank(k, self.v2.observe(k, plant))
        out = np.empty((head.shape[0], head.shape[1] + MAG_CHANNELS))
        out[:, : head.shape[1]] = head
        field = np.ascontiguousarray(plant.states()["field_b_t"], dtype=np.float64)
        run_rows(
            _magnetometer_kernel, k, field, self.rng, self.spike_rng, self.onset, self.biased, self.spiking,
            self.bias_t, self.spike_probability, self.spike_amount, self.noise_t, out, head.shape[1],
            parallel=len(out) >= PARALLEL_MIN_BATCH,
        )  # fmt: skip
        self.next_step = k + 1
        return out


@numba.njit(cache=True, parallel=True)
def _magnetometer_kernel(
    k, field, rng, spike_rng, onset, biased, spiking, bias, probability, amount, scale, out, col
):  # pragma: no cover - compiled
    """The magnetometer's readings of the true body field ``field`` ``(n, 3)`` at step ``k`` into
    ``out[:, col:col + 3]``: ``((B + noise) + bias)``, the bias 0.0 unless in force (added all the
    same), then the spikes (Basilisk's order: noise, bias, faults). Every episode of the step,
    drawing the step's three normals of every episode and three uniforms of every spiking one
    (``sim/pcg64.py``: the numbers numpy's generators give, in the same order; each episode's
    own streams, so the rows are independent)."""
    for e in numba.prange(field.shape[0]):
        faulted = k >= onset[e]
        for i in range(3):  # each stream read in axis order (two streams: interleaving changes nothing)
            z = standard_normal(rng, e)
            u = next_double(spike_rng, e) if spiking[e] else 1.0  # 1.0 never spikes (p < 1)
            b = bias[e, i] if (faulted and biased[e]) else 0.0
            v = (field[e, i] + scale * z) + b
            if faulted and spiking[e] and u <= probability[e, i]:
                v = v * amount[e, i]
            out[e, col + i] = v
