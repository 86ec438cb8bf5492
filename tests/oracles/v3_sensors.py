"""``scftc-v3``'s sensors (``scftc_cli/versions/v3/sim/sensors.py``) as plain numpy array operations:
the readable form of ``V3Sensors.observe``, which runs v2's fused kernel and a small numba pass for
the magnetometer that draws its noise and spikes itself (``sim/pcg64.py``), and is tested against
this form, bit for bit.

Here the v2 part is v2's own readable form (``v2_sensors.observe``), and the magnetometer's draws
come from numpy's generators on the magnetometer's two streams (spawn keys ``NORMALS_KEY`` and
``SPIKES_KEY`` of the episode's noise seed): normals in blocks of ``BLOCK_STEPS`` steps (the
numbers of one long draw, whatever the block), spike uniforms only for spiking episodes. The
generators are this module's own copy of the streams (``draws``, kept on the sensors object), so a
sensors object is read through one of ``observe`` and this form, not both.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.sim.pcg64 import numpy_stream
from scftc_cli.sim.testbed import Plant
from scftc_cli.versions.v3.sim.sensors import MAG_CHANNELS, NORMALS_KEY, SPIKES_KEY, V3Sensors
from tests.oracles import v2_sensors

BLOCK_STEPS = 50


class Draws:
    """One sensors object's magnetometer streams: numpy's generators of the normals (``observe``
    draws the same numbers from its own copies, ``rng``) and of the spike uniforms (spiking
    episodes only), read a block of steps at a time."""

    def __init__(self, sensors: V3Sensors) -> None:
        n = len(sensors.noise_seed)
        self.spike_rows = np.flatnonzero(sensors.spiking)
        self.streams = [numpy_stream(seed, (NORMALS_KEY,)) for seed in sensors.noise_seed]
        self.spike_streams = [numpy_stream(sensors.noise_seed[e], (SPIKES_KEY,)) for e in self.spike_rows]
        self.block = np.empty((n, BLOCK_STEPS, MAG_CHANNELS))
        self.spike_block = np.ones((n, BLOCK_STEPS, MAG_CHANNELS))  # 1.0 never spikes (p < 1)
        self.block_start = -BLOCK_STEPS

    def at(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """``(n, 3)`` standard normals and ``(n, 3)`` spike uniforms of step ``k`` (in order)."""
        if not self.block_start <= k < self.block_start + BLOCK_STEPS:
            if k != self.block_start + BLOCK_STEPS:
                raise ValueError(f"sensors are read step by step; step {k} follows {self.block_start}")
            for e, stream in enumerate(self.streams):
                stream.standard_normal(out=self.block[e])
            for row, stream in zip(self.spike_rows, self.spike_streams, strict=True):
                stream.random(out=self.spike_block[row])
            self.block_start = k
        j = k - self.block_start
        return self.block[:, j], self.spike_block[:, j]


def draws(sensors: V3Sensors) -> Draws:
    """The oracle's magnetometer streams of ``sensors``, made at its first read and kept on it."""
    state = vars(sensors).get("oracle_draws")
    if state is None:
        state = vars(sensors)["oracle_draws"] = Draws(sensors)
    return state


def magnetometer(self: V3Sensors, k: int, field_b_t: np.ndarray) -> np.ndarray:
    """The magnetometer's ``(n, 3)`` readings of the true body field ``field_b_t`` ``(n, 3)``:
    ``((B + noise) + bias)``, the bias 0.0 unless in force (added all the same), then the
    spikes (Basilisk's order: noise, bias, faults)."""
    z, uniform = draws(self).at(k)
    faulted = (k >= self.onset)[:, None]
    out = (field_b_t + self.noise_t * z) + np.where(faulted & self.biased[:, None], self.bias_t, 0.0)
    spike = faulted & self.spiking[:, None] & (uniform <= self.spike_probability)
    return np.where(spike, out * self.spike_amount, out)


def observe(self: V3Sensors, k: int, plant: Plant) -> np.ndarray:
    """``V3Sensors.observe`` as numpy array operations: equal to the bit."""
    head = self._blank(k, v2_sensors.observe(self.v2, k, plant))
    return np.concatenate([head, magnetometer(self, k, plant.states()["field_b_t"])], axis=1)
