"""``scftc-v2``'s sensors: three noisy star-tracker heads, a biased noisy gyro, wheel tachometers.

The sensors read the plant's true state and never change it, so every backend sees identical
observations. Each episode's noise comes from its own stream (``WheelEpisodes.noise_seed``, keyed
like every other draw of the cell), consumed in a fixed order: first the gyro's constant bias
(three uniforms), then 16 standard normals per step (head 1, 2, 3 as three axes each, the gyro's
three axes, the four tachometers). ``observe`` draws each step's normals in its kernel, one
episode's stream after another (``sim/pcg64.py``): exactly the numbers of one long draw from
numpy's generators.

A head's rotation noise is the MRP ``(sigma_st / 4) z``: the rotation vector of an MRP ``p`` is
``4 atan(|p|) p / |p|``, which for 10 arcsec equals ``4 p`` to 1e-14 relative, so each axis gets
``sigma_st`` of rotation noise without a transcendental function (those may round differently on
different CPUs; the observations must not).

``observe``, what every rollout calls, is one numba pass over the batch that also draws the
noise (``sim/pcg64.py``: numpy's PCG64 and ziggurat, the same numbers), in parallel over episodes
on large batches. It runs the floating-point operations of plain numpy array operations in the
same order (those of ``mrp.compose`` included), without contraction into fused multiply-adds:
tests/oracles/v2_sensors.py holds that readable numpy form, its noise drawn from each episode's
``numpy.random.Generator``, and the two agree to the bit.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from scftc_cli.protocol import SensorKnowledge
from scftc_cli.sim.pcg64 import fill_uniform, seeded_states, standard_normal
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, run_rows
from scftc_cli.sim.testbed import Plant, Sensors
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.versions.v2.sim.faults import WheelEpisodes, sensor_code
from scftc_cli.versions.v2.spec import V2, SensorSuite

ARCSEC_TO_RAD = math.pi / (180.0 * 3600.0)
NOISE_CHANNELS = 16
"""Normals per episode per step: 3 heads x 3 axes, 3 gyro axes, 4 tachometers."""


def sensor_knowledge(suite: SensorSuite, dt_s: float) -> SensorKnowledge:
    """The noise figures a controller may know, per sample and in SI units."""
    deg = math.pi / 180.0
    return SensorKnowledge(
        star_tracker_heads=suite.star_tracker_heads,
        star_tracker_noise_rad=suite.star_tracker_noise_arcsec * ARCSEC_TO_RAD,
        gyro_noise_rad_s=suite.gyro_arw_deg_sqrt_h * deg / 60.0 / math.sqrt(dt_s),
        gyro_bias_bound_rad_s=suite.gyro_bias_deg_h * deg / 3600.0,
        tachometer_noise_rad_s=suite.tachometer_noise_rad_s,
    )


class HeadsGyroTachometers(Sensors):
    """The sensors of a batch of ``scftc-v2`` episodes, with each episode's sensor fault from its
    onset step on: ``st_bias`` (one head composed with a constant rotation), ``st_stuck`` (one head
    frozen at what it reported at the onset), ``st_outage`` (every head invalid: zeros, flag 0),
    ``gyro_bias`` (a constant step added to the gyro).

    Observation ``(n, 19)``: three head MRPs (9), three validity flags (3), gyro (3) rad/s,
    tachometers (4) rad/s.
    """

    def __init__(self, episodes: WheelEpisodes, spec: BenchmarkSpec = V2) -> None:
        assert spec.sensors is not None
        self.knowledge = sensor_knowledge(spec.sensors, spec.dt_s)
        self.heads = spec.sensors.star_tracker_heads
        n = episodes.n
        fault = episodes.sensor_fault
        # own, writable copies: the kernel is compiled for writable arrays (a read-only episode
        # table would cost a second compilation)
        self.onset = np.array(episodes.fault.onset_step)
        kind = np.asarray(fault.kind)
        self.biased = kind == sensor_code(spec, "st_bias")
        self.stuck = kind == sensor_code(spec, "st_stuck")
        self.outage = kind == sensor_code(spec, "st_outage")
        self.gyro_step = np.where(
            (kind == sensor_code(spec, "gyro_bias"))[:, None], fault.gyro_bias_step_rad_s, 0.0
        )
        self.head = np.array(fault.head)
        self.head_bias = np.array(fault.head_bias_mrp)
        self.frozen = np.zeros((n, 3))
        self.noise_seed = np.ascontiguousarray(episodes.noise_seed, dtype=np.uint32)
        self.rng = seeded_states(self.noise_seed)  # observe's streams (PCG64(SeedSequence(seed)))
        bound = self.knowledge.gyro_bias_bound_rad_s
        self.gyro_bias = np.empty((n, 3))
        fill_uniform(self.rng, -bound, bound, self.gyro_bias)  # each stream's first three draws
        self.next_step = 0  # the step observe reads next
        # on threads for large batches (``sim.rows``): the same numbers, each episode draws from its
        # own stream
        self.parallel = n >= PARALLEL_MIN_BATCH

    def observe(self, k: int, plant: Plant) -> np.ndarray:
        """``(n, 19)`` observation of the plant's true state at the start of step ``k``, noise
        draws included, in one pass (``_observe_episode`` per episode); steps are read in order,
        each once."""
        if k != self.next_step:
            raise ValueError(f"sensors are read step by step; step {k} follows {self.next_step - 1}")
        states = plant.states()
        sigma, omega, wheels = states["sigma"], states["omega_rad_s"], states["wheel_speed_rad_s"]
        out = np.empty((len(sigma), 9 + self.heads + 3 + wheels.shape[1]))
        run_rows(
            _observe_rows,
            k,
            self.heads,
            _rows(sigma),
            _rows(omega),
            _rows(wheels),
            self.rng,
            self.onset,
            self.biased,
            self.stuck,
            self.outage,
            self.head,
            self.head_bias,
            self.gyro_bias,
            self.gyro_step,
            self.frozen,
            0.25 * self.knowledge.star_tracker_noise_rad,
            self.knowledge.gyro_noise_rad_s,
            self.knowledge.tachometer_noise_rad_s,
            out,
            parallel=self.parallel,
        )
        self.next_step = k + 1
        return out


def _rows(x: np.ndarray) -> np.ndarray:
    """``x`` as a C-contiguous float64 array (the plants' states already are: no copy)."""
    return np.ascontiguousarray(x, dtype=np.float64)


@numba.njit(inline="always")
def _compose(a0, a1, a2, b0, b1, b2):
    """``mrp.compose`` of one row, ``first = a``, ``second = b``: the same operations in the same
    order (``norm2``/``dot`` left to right, ``np.cross(second, first)``, then the shadow switch)."""
    a2n = a0 * a0 + a1 * a1 + a2 * a2
    b2n = b0 * b0 + b1 * b1 + b2 * b2
    ab = a0 * b0 + a1 * b1 + a2 * b2
    c0 = b1 * a2 - b2 * a1
    c1 = b2 * a0 - b0 * a2
    c2 = b0 * a1 - b1 * a0
    qa, qb = 1.0 - a2n, 1.0 - b2n
    den = 1.0 + a2n * b2n - 2.0 * ab
    s0 = ((qa * b0 + qb * a0) - 2.0 * c0) / den
    s1 = ((qa * b1 + qb * a1) - 2.0 * c1) / den
    s2 = ((qa * b2 + qb * a2) - 2.0 * c2) / den
    ss = s0 * s0 + s1 * s1 + s2 * s2
    if ss > 1.0:
        return -s0 / ss, -s1 / ss, -s2 / ss
    return s0, s1, s2


@numba.njit(inline="always")
def _observe_episode(
    e, k, heads, sigma, omega, wheels, rng, onset, biased, stuck, outage, head, head_bias, gyro_bias,
    gyro_step, frozen, head_scale, gyro_scale, tach_scale, out,
):  # fmt: skip
    """``observe`` of episode ``e`` at step ``k`` into ``out[e]`` (19 values); draws the
    episode's 16 normals of the step from ``rng[e]`` in channel order and updates ``frozen[e]``.
    Per head ``h``: the true attitude (composed with the head's offset where ``st_bias`` is in force
    on it), composed with ``head_scale z``; a stuck head's report at the onset is frozen and
    repeated from then on; an outage reports zeros and validity 0. Gyro ``((w + bias) + noise) +
    step`` (the step is 0.0 before the onset, and added all the same, as numpy adds it);
    tachometers ``Omega + noise``.
    """
    faulted = k >= onset[e]
    valid = not (outage[e] and faulted)
    t0, t1, t2 = sigma[e, 0], sigma[e, 1], sigma[e, 2]
    for h in range(heads):
        s0, s1, s2 = t0, t1, t2
        mine = head[e] == h
        if faulted and biased[e] and mine:
            s0, s1, s2 = _compose(t0, t1, t2, head_bias[e, 0], head_bias[e, 1], head_bias[e, 2])
        j = 3 * h
        z0 = standard_normal(rng, e)
        z1 = standard_normal(rng, e)
        z2 = standard_normal(rng, e)
        r0, r1, r2 = _compose(s0, s1, s2, head_scale * z0, head_scale * z1, head_scale * z2)
        if stuck[e] and mine:
            if k == onset[e]:
                frozen[e, 0], frozen[e, 1], frozen[e, 2] = r0, r1, r2
            if faulted:
                r0, r1, r2 = frozen[e, 0], frozen[e, 1], frozen[e, 2]
        if valid:
            out[e, j], out[e, j + 1], out[e, j + 2] = r0, r1, r2
            out[e, 9 + h] = 1.0
        else:
            out[e, j], out[e, j + 1], out[e, j + 2] = 0.0, 0.0, 0.0
            out[e, 9 + h] = 0.0
    g = 9 + heads
    for i in range(3):
        step = gyro_step[e, i] if faulted else 0.0
        noise = gyro_scale * standard_normal(rng, e)
        out[e, g + i] = ((omega[e, i] + gyro_bias[e, i]) + noise) + step
    for i in range(wheels.shape[1]):
        out[e, g + 3 + i] = wheels[e, i] + tach_scale * standard_normal(rng, e)


@numba.njit(parallel=True, cache=True)
def _observe_rows(
    k, heads, sigma, omega, wheels, rng, onset, biased, stuck, outage, head, head_bias, gyro_bias,
    gyro_step, frozen, head_scale, gyro_scale, tach_scale, out,
):  # fmt: skip
    for e in numba.prange(sigma.shape[0]):
        _observe_episode(
            e, k, heads, sigma, omega, wheels, rng, onset, biased, stuck, outage, head, head_bias, gyro_bias,
            gyro_step, frozen, head_scale, gyro_scale, tach_scale, out,
        )  # fmt: skip
