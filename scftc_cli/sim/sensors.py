"""The observation path: what a controller sees, kept apart from the true state.

Sensor faults (SPEC section 2) corrupt only ``obs = [sigma_meas, omega_meas]``; the scoring
always reads the true state.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.sim.mrp import compose


class Sensor:
    """Star tracker + gyro of a batch, with the cell's sensor fault applied.

    Args:
        sensor: ``None`` (healthy), ``bias_*``, ``dropout`` or ``stuck``.
        sigma0: ``(n, 3)`` true initial attitude (what a stuck tracker keeps reporting).
        bias_mrp: ``(n, 3)`` attitude-measurement offset for ``bias_*``.
    """

    def __init__(self, sensor: str | None, sigma0: np.ndarray, bias_mrp: np.ndarray | None) -> None:
        self.sensor, self.sigma0, self.bias_mrp = sensor, sigma0.copy(), bias_mrp

    def observe(self, sigma: np.ndarray, omega_rad_s: np.ndarray) -> np.ndarray:
        """``(n, 6)`` observation of the true state ``sigma``, ``omega_rad_s`` ``(n, 3)``."""
        if self.sensor is None:
            sigma_meas = sigma
        elif self.sensor == "dropout":
            sigma_meas = np.zeros_like(sigma)
        elif self.sensor == "stuck":
            sigma_meas = self.sigma0
        else:
            sigma_meas = compose(sigma, self.bias_mrp)
        return np.concatenate((sigma_meas, omega_rad_s), axis=1)
