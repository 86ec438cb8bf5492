"""``check_controller``: the one checker every registered controller (and submission) passes.

Like gymnasium's ``check_env``: shapes, finite and bounded commands, and determinism — the same
observations after a fresh ``reset`` give bit-identical commands.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.baselines.base import Controller
from scftc_cli.sim.dynamics import NumpyPlant
from scftc_cli.sim.faults import draw_episodes
from scftc_cli.sim.rollout import controller_context, validate_commands
from scftc_cli.sim.sensors import Sensor
from scftc_cli.spec import INERTIA_NOMINAL, SPEC


def _fly(controller: Controller, steps: int, fault_class: str) -> np.ndarray:
    episodes = draw_episodes("train", fault_class, n_faults=3, n_seeds=2)
    inertia = episodes.fault.inertia_scale[:, None] * INERTIA_NOMINAL
    plant = NumpyPlant(episodes.sigma0, episodes.omega0_rad_s, inertia, SPEC.plant.dt_s)
    sensor = Sensor(None, episodes.sigma0, None)
    controller.reset(episodes.n, controller_context(controller, episodes))
    sigma, omega = episodes.sigma0, episodes.omega0_rad_s
    out = []
    for _ in range(steps):
        command = validate_commands(controller.act(sensor.observe(sigma, omega)), episodes.n)
        if np.any(np.abs(command) > 1.0):
            raise AssertionError(f"{type(controller).__name__} returned commands outside [-1, 1]")
        out.append(command.copy())
        torque = (command * episodes.fault.gain + episodes.fault.bias) * SPEC.plant.tau_max_nm
        sigma, omega = plant.step(torque)
    return np.stack(out, axis=1)


def check_controller(controller: Controller, steps: int = 40) -> None:
    """Raise ``AssertionError`` (or ``ControllerError``) if ``controller`` breaks the protocol."""
    for fault_class in ("gain_bias", "loss"):
        first = _fly(controller, steps, fault_class)
        again = _fly(controller, steps, fault_class)
        if not np.array_equal(first, again):
            raise AssertionError(f"{type(controller).__name__} is not deterministic after reset()")
