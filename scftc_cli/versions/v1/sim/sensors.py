"""``scftc-v1``'s observation path: what a controller sees, kept apart from the true state.

Sensor faults corrupt only ``obs = [sigma_meas, omega_meas]``; the scoring always reads the true
state. There is no noise in ``scftc-v1``.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.sim.mrp import compose
from scftc_cli.sim.testbed import Plant, Sensors
from scftc_cli.versions.v1.sim.faults import RigidEpisodes
from scftc_cli.versions.v1.spec import V1


class StarTrackerAndGyro(Sensors):
    """Star tracker + gyro of a batch, with the cell's sensor fault applied to the star tracker.

    By the fault's kind (``spec.sensor_classes``): ``bias``, the attitude composed with a constant
    per-episode rotation; ``dropout``, zeros for the whole episode; ``stuck``, frozen at the true
    initial attitude. The gyro is never faulted.
    """

    def __init__(self, episodes: RigidEpisodes) -> None:
        self.sensor = episodes.sensor
        self.kind = None if episodes.sensor is None else V1.sensor_class(episodes.sensor).kind
        self.sigma0 = episodes.sigma0.copy()
        self.bias_mrp = episodes.sensor_bias_mrp

    def observe(self, k: int, plant: Plant) -> np.ndarray:
        """``(n, 6)`` observation of the plant's true state."""
        states = plant.states()
        sigma, omega = states["sigma"], states["omega_rad_s"]
        if self.kind is None:
            sigma_meas = sigma
        elif self.kind == "dropout":
            sigma_meas = np.zeros_like(sigma)
        elif self.kind == "stuck":
            sigma_meas = self.sigma0
        elif self.bias_mrp is not None:
            sigma_meas = compose(sigma, self.bias_mrp)
        else:
            raise ValueError(f"sensor fault {self.sensor} without its attitude offset")
        return np.concatenate((sigma_meas, omega), axis=1)
