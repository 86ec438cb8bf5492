"""The per-wheel pieces around ``scftc-v2``'s RMA student (``rma.py``): the noise of one torque
sample, the CUSUM change test that re-opens a latched estimate, and the persistence-of-excitation
latch itself (the settings are ``student.py``'s ``DetectorConfig`` and ``LatchConfig``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from scftc_cli.protocol import Context
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, as_f64, run_rows
from scftc_cli.versions.v2.controllers.law import wheels_of
from scftc_cli.versions.v2.controllers.student import DetectorConfig, LatchConfig


def noise_sigma(context: Context) -> float:
    """1-sigma noise of one ``y`` sample: two tachometer readings (the gyro's share is ~1e-4 of
    it), 5 % added for the integration's rounding (measured: 9.2e-4 against 9.0e-4)."""
    wheels, sensors = wheels_of(context), context.sensors
    assert sensors is not None
    per_reading = wheels.spin_inertia_kgm2 * sensors.tachometer_noise_rad_s / (wheels.u_max_nm * context.dt_s)
    return 1.05 * math.sqrt(2.0) * per_reading


class CusumDetector:
    """Per-wheel CUSUM on the normalized innovation (``DetectorConfig``), ``(n, m)``."""

    def __init__(self, config: DetectorConfig, sigma_y: float, shape: tuple[int, int]) -> None:
        self.config, self.sigma2 = config, sigma_y * sigma_y
        self.statistic = np.zeros(shape)
        self.since = np.zeros(shape, dtype=np.int64)  # steps since the last restart

    def update(
        self, innovation: np.ndarray, command: np.ndarray, valid: np.ndarray, spread: np.ndarray | float = 0.0
    ) -> np.ndarray:
        """Fold in one step's innovation ``e`` under ``command`` where ``valid``; ``spread`` is the
        variance the offset estimate adds to the prediction (``phi' P phi`` of the observer: large
        where the data never excited it, e.g. the first reversal of a wheel); returns the alarms
        ``(n, m)`` (their statistic is cleared)."""
        cfg = self.config
        z2 = innovation * innovation / (self.sigma2 + (cfg.rho * command) ** 2 + spread)
        grown = self.statistic + np.minimum(z2, cfg.z2_max) - cfg.drift
        self.statistic = np.where(valid, np.maximum(grown, 0.0), self.statistic)
        self.since += 1
        alarm = (self.statistic > cfg.threshold) & (self.since > cfg.refractory)
        self.statistic[alarm] = 0.0
        self.since[alarm] = 0
        return alarm


class WheelLatch:
    """The per-wheel latch (``LatchConfig``) of a batch ``(n, m)``, restartable per wheel.

    Per step: ``gain = latch.update(raw, excitation)``; wheels that latch keep the estimate of the
    step they latched at until ``restart``.
    """

    def __init__(self, config: LatchConfig, shape: tuple[int, int]) -> None:
        self.config = config
        self.history = np.zeros((config.window + 1, *shape))  # ring buffer of raw estimates
        self.count = np.zeros(shape, dtype=np.int64)  # raw estimates since the restart
        self.latched = np.zeros(shape, dtype=bool)
        self.frozen = np.zeros(shape)

    def restart(self, rows: np.ndarray) -> None:
        self.count[rows] = 0
        self.latched[rows] = False

    def update(self, raw: np.ndarray, excitation: np.ndarray) -> np.ndarray:
        """Fold in the live estimate ``raw`` ``(n, m)``; returns the estimate to use. One compiled
        pass over the episodes (``_latch_rows``; tests/oracles/v2_latch.py holds a readable numpy
        form, the same bits)."""
        cfg = self.config
        out = np.empty(self.frozen.shape)
        run_rows(
            _latch_rows, self.history, self.count, self.latched, self.frozen,
            as_f64(raw), as_f64(excitation),
            int(cfg.window), int(cfg.min_steps), int(cfg.max_steps), float(cfg.tolerance),
            float(cfg.min_excitation), out, parallel=len(out) >= PARALLEL_MIN_BATCH,
        )  # fmt: skip
        return out


@numba.njit(cache=True, parallel=True)
def _latch_rows(
    history,
    count,
    latched,
    frozen,
    raw,
    excitation,
    window,
    min_steps,
    max_steps,
    tolerance,
    min_excitation,
    out,
):  # pragma: no cover
    """``WheelLatch.update`` of every wheel of every episode, the state (``history``
    ``(window + 1, n, m)``, ``count``, ``latched``, ``frozen`` ``(n, m)``) updated in place and the
    estimate to use written into ``out``. The window's spread is ``max - min`` of its estimates, NaN
    if any is NaN (as numpy's reductions give it); only its comparison is used, where the sign of
    a zero spread does not matter."""
    slots = window + 1
    for e in numba.prange(raw.shape[0]):
        for i in range(raw.shape[1]):
            value = raw[e, i]
            history[count[e, i] % slots, e, i] = value
            count[e, i] += 1
            full = count[e, i] > window
            still = False
            if full:
                top, bottom, nan = history[0, e, i], history[0, e, i], False
                for k in range(slots):
                    v = history[k, e, i]
                    nan |= v != v
                    top = max(top, v)
                    bottom = min(bottom, v)
                spread = np.nan if nan else top - bottom
                size = abs(value)
                if size < 0.1:
                    size = 0.1
                still = spread <= tolerance * size
            due = still or count[e, i] > max_steps
            if not latched[e, i] and count[e, i] > min_steps and due and excitation[e, i] >= min_excitation:
                frozen[e, i] = value
                latched[e, i] = True
            out[e, i] = frozen[e, i] if latched[e, i] else value
