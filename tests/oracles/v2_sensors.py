"""``scftc-v2``'s sensors (``scftc_cli/versions/v2/sim/sensors.py``) as plain numpy array operations:
the readable form of ``HeadsGyroTachometers.observe``, which runs the same floating-point operations
in the same order as one numba pass that also draws the noise (``sim/pcg64.py``), and is tested
against this form, bit for bit.

Here the noise comes from each episode's ``numpy.random.Generator``, in blocks of ``BLOCK_STEPS``
steps: the numbers of one long draw, whatever the block, and the numbers ``observe`` draws. The
generators are this module's own copy of the streams (``noise``, kept on the sensors object), so a
sensors object is read through one of ``observe`` and this form, not both.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.sim.mrp import compose
from scftc_cli.sim.pcg64 import numpy_stream
from scftc_cli.sim.testbed import Plant
from scftc_cli.versions.v2.sim.sensors import NOISE_CHANNELS, HeadsGyroTachometers

BLOCK_STEPS = 50


class Noise:
    """One sensors object's noise streams: numpy's generators, standing where ``observe``'s
    started (after the gyro bias's three uniforms), read a block of steps at a time."""

    def __init__(self, sensors: HeadsGyroTachometers) -> None:
        bound = sensors.knowledge.gyro_bias_bound_rad_s
        self.streams = [numpy_stream(seed) for seed in sensors.noise_seed]
        for stream in self.streams:
            stream.uniform(-bound, bound, 3)
        self.block = np.empty((len(self.streams), BLOCK_STEPS, NOISE_CHANNELS))
        self.block_start = -BLOCK_STEPS

    def normals(self, k: int) -> np.ndarray:
        """``(n, 16)`` standard normals of step ``k`` (steps are observed in order)."""
        if not self.block_start <= k < self.block_start + BLOCK_STEPS:
            if k != self.block_start + BLOCK_STEPS:
                raise ValueError(f"sensors are read step by step; step {k} follows {self.block_start}")
            for e, stream in enumerate(self.streams):
                stream.standard_normal(out=self.block[e])
            self.block_start = k
        return self.block[:, k - self.block_start]


def noise(sensors: HeadsGyroTachometers) -> Noise:
    """The oracle's streams of ``sensors``, made at its first read and kept on it."""
    state = vars(sensors).get("oracle_noise")
    if state is None:
        state = vars(sensors)["oracle_noise"] = Noise(sensors)
    return state


def observe(self: HeadsGyroTachometers, k: int, plant: Plant) -> np.ndarray:
    """``HeadsGyroTachometers.observe`` as numpy array operations, its noise drawn from numpy's
    generators (``noise``): equal to the bit."""
    states = plant.states()
    sigma, omega, wheels = states["sigma"], states["omega_rad_s"], states["wheel_speed_rad_s"]
    n = len(sigma)
    z = noise(self).normals(k)
    faulted = k >= self.onset
    out = np.empty((n, 9 + self.heads + 3 + wheels.shape[1]))
    head_noise = (0.25 * self.knowledge.star_tracker_noise_rad) * z[:, :9]
    for h in range(self.heads):
        this = self.head == h
        seen = sigma
        biased = np.flatnonzero(faulted & self.biased & this)
        if len(biased):
            seen = sigma.copy()
            seen[biased] = compose(sigma[biased], self.head_bias[biased])
        reported = compose(seen, head_noise[:, 3 * h : 3 * h + 3])
        stuck = self.stuck & this
        np.copyto(self.frozen, reported, where=(stuck & (k == self.onset))[:, None])
        reported = np.where((stuck & faulted)[:, None], self.frozen, reported)
        valid = ~(self.outage & faulted)
        out[:, 3 * h : 3 * h + 3] = np.where(valid[:, None], reported, 0.0)
        out[:, 9 + h] = valid
    g = 9 + self.heads
    gyro_noise = self.knowledge.gyro_noise_rad_s * z[:, 9:12]
    out[:, g : g + 3] = omega + self.gyro_bias + gyro_noise + np.where(faulted[:, None], self.gyro_step, 0.0)
    out[:, g + 3 :] = wheels + self.knowledge.tachometer_noise_rad_s * z[:, 12:16]
    return out
