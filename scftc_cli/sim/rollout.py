"""The closed loop, once for every benchmark version: sensors -> controller -> plant, one batch.

Gate statistics are accumulated on the fly (the dwell-window maximum, the minimum, the final
error, the last step outside the settled tolerance), so a large batch never stores its
trajectories unless asked to. Everything version-specific comes from the episodes' ``Testbed``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from scftc_cli.errors import ControllerError
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.sim.episodes import Episodes
from scftc_cli.sim.mrp import angle_deg_from_norm2, largest_norm2_within
from scftc_cli.sim.testbed import testbed


@dataclass(frozen=True)
class Rollout:
    """What a batch of episodes produced, on the true state.

    Attributes:
        final_error_deg: ``(n,)`` pointing error after the last step.
        dwell_max_error_deg: ``(n,)`` largest error over the final dwell window.
        min_error_deg: ``(n,)`` smallest error over steps 1..steps.
        settling_time_s: ``(n,)`` time of the first sample after which the error never again exceeds
            the settled tolerance; NaN where the last sample exceeds it.
        error_deg: ``(n, steps)`` full error history, only when trajectories were recorded.
        states: name -> ``(n, steps + 1, d)`` true states incl. the initial one, likewise.
        commands: ``(n, steps, action_dim)`` clipped commands, likewise.
    """

    final_error_deg: np.ndarray
    dwell_max_error_deg: np.ndarray
    min_error_deg: np.ndarray
    settling_time_s: np.ndarray
    error_deg: np.ndarray | None = None
    states: dict[str, np.ndarray] = field(default_factory=dict)
    commands: np.ndarray | None = None

    @property
    def sigma(self) -> np.ndarray:
        """``(n, steps + 1, 3)`` recorded true attitude (MRP)."""
        return self.states["sigma"]

    @property
    def omega_rad_s(self) -> np.ndarray:
        """``(n, steps + 1, 3)`` recorded true body rate."""
        return self.states["omega_rad_s"]


def validate_commands(commands: object, n: int, width: int) -> np.ndarray:
    """Accept only a finite float array of shape ``(n, width)``; anything else is a controller bug."""
    if not isinstance(commands, np.ndarray):
        raise ControllerError(f"act() must return a numpy array, got {type(commands).__name__}")
    if commands.shape != (n, width):
        raise ControllerError(f"act() must return shape ({n}, {width}), got {commands.shape}")
    if commands.dtype.kind != "f":
        raise ControllerError(f"act() must return floats, got dtype {commands.dtype}")
    if not np.all(np.isfinite(commands)):
        raise ControllerError("act() returned NaN or inf commands; return finite values in [-1, 1]")
    return commands


def rollout(
    controller: Controller,
    episodes: Episodes,
    *,
    backend: str = "numpy",
    record: bool = False,
    steps: int | None = None,
    progress: Progress = NO_PROGRESS,
) -> Rollout:
    """Fly ``controller`` through every episode of ``episodes`` at once.

    Args:
        backend: ``numpy`` (fused, default), ``reference`` or ``basilisk``.
        record: keep full trajectories (states, errors, commands).
        steps: fly only this many steps (a prefix; default the whole episode).
        progress: advanced by one after each step.
    """
    bed = testbed(episodes.benchmark)
    spec = bed.spec
    n, steps = episodes.n, spec.steps if steps is None else steps
    plant = bed.plant(episodes, backend)
    sensors = bed.sensors(episodes)
    controller.reset(n, bed.context(episodes, controller.privileged))

    # Gates are tracked on |sigma|^2 and converted once at the end: the angle is monotone in it.
    dwell_start = steps - spec.gates.dwell_steps
    settled_norm2 = largest_norm2_within(spec.gates.settled_deg)
    dwell_max = np.zeros(n)
    min_norm2 = np.full(n, np.inf)
    last_outside = np.full(n, -1)  # last step whose error exceeded the settled tolerance
    if record:
        errors, commands = np.empty((n, steps)), np.empty((n, steps, spec.action_dim))
        history = {name: np.empty((n, steps + 1, value.shape[1])) for name, value in plant.states().items()}
        for name, value in plant.states().items():
            history[name][:, 0] = value
    sigma_norm2 = np.zeros(n)
    for k in range(steps):
        obs = sensors.observe(k, plant)
        command = np.clip(validate_commands(controller.act(obs), n, spec.action_dim), -1.0, 1.0)
        sigma_norm2 = plant.step(k, command)
        np.minimum(min_norm2, sigma_norm2, out=min_norm2)
        np.copyto(last_outside, k, where=sigma_norm2 > settled_norm2)
        if k >= dwell_start:
            np.maximum(dwell_max, sigma_norm2, out=dwell_max)
        if record:
            errors[:, k], commands[:, k] = angle_deg_from_norm2(sigma_norm2), command
            for name, value in plant.states().items():
                history[name][:, k + 1] = value
        progress.advance(1)
    # sample k (after step k) is at time (k + 1) dt; the error stays within from the next sample on
    settling = np.where(last_outside < steps - 1, (last_outside + 2) * spec.dt_s, np.nan)
    stats = (
        angle_deg_from_norm2(sigma_norm2),
        angle_deg_from_norm2(dwell_max),
        angle_deg_from_norm2(min_norm2),
        settling,
    )
    if not record:
        return Rollout(*stats)
    return Rollout(*stats, error_deg=errors, states=history, commands=commands)
