"""The closed loop: sensor -> controller -> actuator fault -> plant, one batch of episodes.

Gate statistics are accumulated on the fly (the dwell-window maximum, the minimum, the final
error), so a large batch never stores its 400-step trajectories unless they are asked for.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.base import Context, Controller, TrueFault
from scftc_cli.errors import ControllerError
from scftc_cli.sim.dynamics import Plant
from scftc_cli.sim.fast import FastPlant
from scftc_cli.sim.faults import Episodes
from scftc_cli.sim.mrp import angle_deg_from_norm2
from scftc_cli.sim.sensors import Sensor
from scftc_cli.spec import INERTIA_NOMINAL, SPEC


@dataclass(frozen=True)
class Rollout:
    """What a batch of episodes produced, on the true state.

    Attributes:
        final_error_deg: ``(n,)`` pointing error after the last step.
        dwell_max_error_deg: ``(n,)`` largest error over the final dwell window.
        min_error_deg: ``(n,)`` smallest error over steps 1..steps.
        error_deg: ``(n, steps)`` full error history, only when trajectories were recorded.
        sigma, omega_rad_s: ``(n, steps + 1, 3)`` true states incl. the initial one, likewise.
        commands: ``(n, steps, 3)`` clipped commands, likewise.
    """

    final_error_deg: np.ndarray
    dwell_max_error_deg: np.ndarray
    min_error_deg: np.ndarray
    error_deg: np.ndarray | None = None
    sigma: np.ndarray | None = None
    omega_rad_s: np.ndarray | None = None
    commands: np.ndarray | None = None


def validate_commands(commands: object, n: int) -> np.ndarray:
    """Accept only a finite float array of shape ``(n, 3)``; anything else is a controller bug."""
    if not isinstance(commands, np.ndarray):
        raise ControllerError(f"act() must return a numpy array, got {type(commands).__name__}")
    if commands.shape != (n, 3):
        raise ControllerError(f"act() must return shape ({n}, 3), got {commands.shape}")
    if commands.dtype.kind != "f":
        raise ControllerError(f"act() must return floats, got dtype {commands.dtype}")
    if not np.all(np.isfinite(commands)):
        raise ControllerError("act() returned NaN or inf commands; return finite values in [-1, 1]")
    return commands


def controller_context(controller: Controller, episodes: Episodes) -> Context:
    """The context a controller may see: the true fault only if it is privileged."""
    fault = None
    if controller.privileged:
        fault = TrueFault(theta=episodes.fault.theta, beta=episodes.fault.beta)
    return Context(n=episodes.n, fault=fault)


PlantFactory = Callable[[np.ndarray, np.ndarray, np.ndarray, float], Plant]


def rollout(
    controller: Controller,
    episodes: Episodes,
    *,
    plant_factory: PlantFactory = FastPlant,
    record: bool = False,
    on_step: Callable[[int], None] | None = None,
) -> Rollout:
    """Fly ``controller`` through every episode of ``episodes`` at once.

    Args:
        plant_factory: builds the backend from ``(sigma0, omega0, inertia (n, 3), dt_s)``.
        record: keep full trajectories (states, errors, commands).
        on_step: called with the step index after each step (progress bars).
    """
    plant_spec = SPEC.plant
    n, steps = episodes.n, plant_spec.steps
    inertia = episodes.fault.inertia_scale[:, None] * INERTIA_NOMINAL
    plant = plant_factory(episodes.sigma0, episodes.omega0_rad_s, inertia, plant_spec.dt_s)
    sensor = Sensor(episodes.sensor, episodes.sigma0, episodes.sensor_bias_mrp)
    gain, bias = episodes.fault.gain, episodes.fault.bias
    controller.reset(n, controller_context(controller, episodes))

    # Gates are tracked on |sigma|^2 and converted once at the end: the angle is monotone in it.
    dwell_start = steps - SPEC.gates.dwell_steps
    dwell_max = np.zeros(n)
    min_norm2 = np.full(n, np.inf)
    if record:
        errors, commands = np.empty((n, steps)), np.empty((n, steps, 3))
        sigmas, omegas = np.empty((n, steps + 1, 3)), np.empty((n, steps + 1, 3))
        sigmas[:, 0], omegas[:, 0] = episodes.sigma0, episodes.omega0_rad_s
    sigma, omega = episodes.sigma0, episodes.omega0_rad_s
    for k in range(steps):
        command = np.clip(validate_commands(controller.act(sensor.observe(sigma, omega)), n), -1, 1)
        sigma, omega, sigma_norm2 = plant.actuate(command, gain, bias, plant_spec.tau_max_nm)
        np.minimum(min_norm2, sigma_norm2, out=min_norm2)
        if k >= dwell_start:
            np.maximum(dwell_max, sigma_norm2, out=dwell_max)
        if record:
            errors[:, k], commands[:, k] = angle_deg_from_norm2(sigma_norm2), command
            sigmas[:, k + 1], omegas[:, k + 1] = sigma, omega
        if on_step is not None:
            on_step(k)
    stats = (
        angle_deg_from_norm2(sigma_norm2),
        angle_deg_from_norm2(dwell_max),
        angle_deg_from_norm2(min_norm2),
    )
    if not record:
        return Rollout(*stats)
    return Rollout(*stats, errors, sigmas, omegas, commands)
