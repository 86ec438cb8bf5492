"""``scftc/AttitudeFTC-v3``: ``scftc-v3``'s agile mission (orbit, environment torques, wheels and
magnetorquer rods, v2's sensors plus a magnetometer, three pointing windows) as a gymnasium
environment.

An episode is one whole ``scftc-v3`` episode (docs/benchmark-v3.md): 2400 steps of 0.5 s, three
pointing windows joined by slews, then truncation. Each episode's fault, orbit, mission and noise
come from the benchmark's own sampler (``sim.faults.pinned_episodes``) keyed by 16 random bytes
from the environment's generator instead of the pinned cell's index: the pinned draws'
distribution by construction, never a pinned episode. Its cell is an actuator class uniform over
``fault_classes`` and a sensor class uniform over ``sensor_faults`` (``None``: healthy sensors; a
sensor fault rides on a ``sign`` fault, as in the benchmark's sensor cells).

The agent observes exactly what a benchmark controller observes, the 26 values of the mission's
sensors (v2's 19, the magnetometer in tesla, the window's target MRP, the time left in the window;
optionally with its previous action appended), and commands four wheel torques and three rod
dipoles, each in [-1, 1]; the fault is never part of the observation or of ``info``. The reward is
``scftc/AttitudeFTC-v2``'s shape on the *measured* error to the current target: ``e`` the
principal angle of the fused attitude (``AttitudeFuser``) relative to the target and ``w`` the gyro
reading,

    r = -e_deg / 180 - |w| + 0.5 exp(-e_deg / 1 deg);

``info["pointing_error_deg"]`` reports the *true* error to the target, for logging only.

``AttitudeFTCv3Env`` is the single-episode ``gymnasium.Env`` (passes ``check_env``);
``AttitudeFTCv3VectorEnv`` steps ``num_envs`` episodes as one call of the fused kernel (same-step
autoreset: every episode has the same horizon; the last observation is in ``info["final_obs"]``).
``reset(options={"episodes": e})`` flies the given ``AgileEpisodes``. Train only on the ``train``
split; the ``test`` split exists here for evaluation, never for tuning.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar

import numpy as np
from gymnasium import spaces

from scftc_cli.envs.batch import BatchEnv, BatchVectorEnv, EpisodeBatch
from scftc_cli.versions.v2.envs import WheelBatch
from scftc_cli.versions.v3.controllers.law import TARGET, attitude_error
from scftc_cli.versions.v3.sim.faults import AgileEpisodes, pinned_episodes
from scftc_cli.versions.v3.sim.testbed import TESTBED
from scftc_cli.versions.v3.spec import V3, AgilePlant

ENV_ID = "scftc/AttitudeFTC-v3"
DEFAULT_CLASSES: tuple[str, ...] = V3.fault_classes
DEFAULT_SENSORS: tuple[str | None, ...] = (None,)
ACTION_DIM = V3.action_dim
SALT_BYTES = 16
MAGNETOMETER_BOUND_T = 1e-3
"""No reading reaches it: the field is below 6e-5 T on these orbits, a bias adds at most 1.5e-5 T
and a spike doubles a reading."""
assert isinstance(V3.plant, AgilePlant)
PLANT: AgilePlant = V3.plant
WINDOW_S = PLANT.window_steps * PLANT.dt_s


def sample_episodes(
    rng: np.random.Generator,
    n: int,
    split: str,
    classes: tuple[str, ...] = DEFAULT_CLASSES,
    sensors: tuple[str | None, ...] = DEFAULT_SENSORS,
    pinned: Callable[..., AgileEpisodes] = pinned_episodes,
) -> AgileEpisodes:
    """``n`` fresh episodes of ``split``: per episode, its sensor class and (without a sensor
    fault) its actuator class uniform, then the benchmark's sampler (``pinned``: v3's, or a version
    built on its mission) keyed by ``SALT_BYTES`` random bytes (uncached)."""
    parts = []
    for _ in range(n):
        sensor = sensors[int(rng.integers(len(sensors)))]
        fault_class = V3.sensor_base_class if sensor is not None else classes[int(rng.integers(len(classes)))]
        salt = rng.bytes(SALT_BYTES)
        parts.append(pinned.__wrapped__(split, fault_class, sensor, 1, 1, salt, 0, 1))  # type: ignore[attr-defined]
    return AgileEpisodes.concat(parts)


class MissionBatch(EpisodeBatch):
    """``n`` ``scftc-v3`` episodes flown together (``EpisodeBatch``); the reward reads the fused
    attitude's error to the window's target."""

    spec = V3
    testbed = TESTBED
    episodes_type = AgileEpisodes
    default_classes = DEFAULT_CLASSES
    default_sensors = DEFAULT_SENSORS
    pinned: ClassVar[Callable[..., AgileEpisodes]] = staticmethod(pinned_episodes)

    @classmethod
    def observation_space(cls, include_prev_action: bool, dtype: type) -> spaces.Box:
        lead = WheelBatch.observation_space(False, dtype)  # v2's 19 readings lead, bounded as v2 bounds them
        low = [-MAGNETOMETER_BOUND_T] * 3 + [-1.0] * 3 + [0.0]  # the magnetometer, target MRP, time left
        high = [MAGNETOMETER_BOUND_T] * 3 + [1.0] * 3 + [WINDOW_S]
        if include_prev_action:
            low, high = low + [-1.0] * ACTION_DIM, high + [1.0] * ACTION_DIM
        return spaces.Box(
            np.concatenate([lead.low, np.array(low, dtype=dtype)]),
            np.concatenate([lead.high, np.array(high, dtype=dtype)]),
            dtype=dtype,
        )

    def draw(self, rng: np.random.Generator) -> AgileEpisodes:
        return sample_episodes(rng, self.n, self.split, self.fault_classes, self.sensor_faults, self.pinned)

    def measured_error(self, obs: np.ndarray, fused_sigma: np.ndarray) -> np.ndarray:
        return attitude_error(fused_sigma, obs[:, TARGET])


class AttitudeFTCv3Env(BatchEnv):
    """One whole ``scftc-v3`` episode per ``reset`` (see the module docstring and ``BatchEnv``; the
    default classes are all eleven actuator classes, ``nominal`` included)."""

    batch_type = MissionBatch


class AttitudeFTCv3VectorEnv(BatchVectorEnv):
    """``num_envs`` ``scftc-v3`` episodes stepped as one call of the fused kernel (same-step
    autoreset; ``BatchVectorEnv``)."""

    batch_type = MissionBatch
