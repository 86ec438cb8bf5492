"""``scftc/AttitudeFTC-v2``: ``scftc-v2``'s reaction-wheel plant, sensors and fault taxonomy as a
gymnasium environment.

An episode is one ``scftc-v2`` episode (docs/benchmark-v2.md): a fault drawn from the chosen split,
actuator classes and sensor classes by ``sim.faults.sample_episodes_batch`` (the pinned draws'
distribution), starting mid-flight at its onset; 400 steps of 0.5 s, then truncation. The agent
observes exactly what a benchmark controller observes, the 19 values of ``HeadsGyroTachometers``
(three star-tracker heads as MRPs, their validity flags, the gyro, four tachometers; optionally
with its previous action appended), and commands four normalized motor torques in [-1, 1]; the
fault is never part of the observation or of ``info``. The reward is shaped on the *measured*
state: ``e`` the principal angle of the fused attitude (``controllers.law.AttitudeFuser``: the
median of the valid heads, propagated with the gyro through an outage) and ``w`` the gyro reading,

    r = -e_deg / 180 - |w| + 0.5 exp(-e_deg / 1 deg)

(``scftc/AttitudeFTC-v1``'s shape); ``info["pointing_error_deg"]`` reports the *true* error, for
logging only.

``AttitudeFTCv2Env`` is the single-episode ``gymnasium.Env`` (passes ``check_env``);
``AttitudeFTCv2VectorEnv`` steps ``num_envs`` episodes as one call of the fused wheel kernel
(``backend="numpy"``; same-step autoreset as v1's: every episode shares the fixed horizon, so they
reset together and the last observation is in ``info["final_obs"]``). Observations are float32 by
default (``dtype=np.float64``: the benchmark's values to the bit). ``reset(options={"episodes":
e})`` flies the given ``WheelEpisodes`` (as many as environments) instead of drawing new ones.
Train only on the ``train`` split; the ``test`` split exists here for evaluation, never for tuning.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import VectorEnv
from gymnasium.vector.utils import batch_space
from gymnasium.vector.vector_env import AutoresetMode

from scftc_cli.errors import UsageError
from scftc_cli.sim.mrp import angle_deg_from_norm2, principal_angle_deg
from scftc_cli.versions.v2.controllers.law import AttitudeFuser, split_observation
from scftc_cli.versions.v2.sim.faults import WheelEpisodes, sample_episodes_batch
from scftc_cli.versions.v2.sim.testbed import CONSTANTS, TESTBED
from scftc_cli.versions.v2.spec import V2

ENV_ID = "scftc/AttitudeFTC-v2"
"""The suffix is the benchmark version. Gymnasium reads it as a newer version of
``AttitudeFTC-v1`` and would warn v1 users that v1 "is out of date"; scftc-v2 is another track,
so registering the ids silences that one warning (``envs/__init__.py``)."""
DEFAULT_CLASSES: tuple[str, ...] = V2.fault_classes
DEFAULT_SENSORS: tuple[str | None, ...] = (None,)
ACTION_DIM = V2.action_dim
# Bounds no episode can reach. The wheels' torques are internal, so the total momentum keeps its
# initial size (<= ~2.1 N m s: hub rates <= 0.035 rad/s, wheels <= 1000 rpm); the motor cannot
# spin a wheel past Omega_max by more than one step (u_max dt / Js ~ 16 rad/s), so
# |Omega| < 1.1 Omega_max and |w| <= (2.1 + Js |G| |Omega|) / (0.7 * 6 kg m^2) < 2 rad/s.
GYRO_BOUND_RAD_S = 10.0
TACHOMETER_BOUND_RAD_S = 2.0 * CONSTANTS.omega_max_rad_s


def shaped_reward(sigma_meas: np.ndarray, gyro_rad_s: np.ndarray) -> np.ndarray:
    """``(n,)`` reward of the fused attitude ``(n, 3)`` and the gyro reading ``(n, 3)`` after a step."""
    error_deg = principal_angle_deg(sigma_meas)
    rate = np.linalg.norm(gyro_rad_s, axis=1)
    return -error_deg / 180.0 - rate + 0.5 * np.exp(-error_deg / 1.0)


def _observation_space(include_prev_action: bool, dtype: type) -> spaces.Box:
    heads = V2.sensors.star_tracker_heads if V2.sensors else 0
    low = (
        [-1.0] * 3 * heads  # MRPs on the shadow-switched branch: |sigma| <= 1
        + [0.0] * heads
        + [-GYRO_BOUND_RAD_S] * 3
        + [-TACHOMETER_BOUND_RAD_S] * CONSTANTS.n_wheels
        + ([-1.0] * ACTION_DIM if include_prev_action else [])
    )
    low_arr: np.ndarray = np.array(low, dtype=dtype)
    high_arr = -low_arr
    high_arr[3 * heads : 4 * heads] = 1.0
    return spaces.Box(low_arr, high_arr, dtype=dtype)


def _action_space() -> spaces.Box:
    return spaces.Box(-1.0, 1.0, (ACTION_DIM,), dtype=np.float32)


def checked_action(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``action`` as float64 (a float32 action converts exactly); a wrong shape or a non-finite
    value is a ``UsageError`` that names the expected shape."""
    action = np.asarray(action)
    if action.shape != shape:
        raise UsageError(f"action must have shape {shape} (one command per wheel), got {action.shape}")
    if not np.all(np.isfinite(action)):
        raise UsageError("action must be finite, got NaN or inf")
    return action.astype(np.float64)


def _check_dtype(dtype: Any) -> type:
    chosen = np.dtype(dtype).type
    if chosen not in (np.float32, np.float64):
        raise UsageError(f"dtype must be float32 or float64, got {np.dtype(dtype).name}")
    return chosen


class WheelBatch:
    """``n`` ``scftc-v2`` episodes flown together: plant on the fused kernel, the benchmark's
    sensors, and the fuser that measures the reward; the core of both environments.

    Args:
        n: episodes per batch.
        split, fault_classes, sensor_faults: what ``reset`` draws (``None`` in ``sensor_faults``:
            healthy sensors); checked here, so a bad name fails at construction.
        include_prev_action: append the previous clipped action to the observation.
        backend: ``numpy`` (fused, default) or ``reference``.
    """

    def __init__(
        self,
        n: int,
        split: str = "train",
        fault_classes: tuple[str, ...] = DEFAULT_CLASSES,
        sensor_faults: tuple[str | None, ...] = DEFAULT_SENSORS,
        include_prev_action: bool = False,
        backend: str = "numpy",
    ) -> None:
        if n < 1:
            raise UsageError("num_envs must be at least 1")
        if not fault_classes or not sensor_faults:
            raise UsageError("name at least one fault class and one sensor class (None: healthy)")
        for c in fault_classes:
            V2.check_cell(split, c)
        for s in sensor_faults:
            if s is not None:
                V2.check_cell(split, V2.sensor_base_class, s)
        if backend not in ("numpy", "reference"):
            raise UsageError(f"backend must be numpy or reference, got {backend!r}")
        self.n, self.split = n, split
        self.fault_classes, self.sensor_faults = tuple(fault_classes), tuple(sensor_faults)
        self.include_prev_action = include_prev_action
        self.backend = backend
        self.k = 0

    def reset(self, rng: np.random.Generator, episodes: WheelEpisodes | None = None) -> np.ndarray:
        """Draw ``n`` fresh episodes from ``rng`` (or fly ``episodes``); the first observations
        ``(n, 19 [+ 4])`` float64."""
        if episodes is None:
            episodes = sample_episodes_batch(rng, self.n, self.split, self.fault_classes, self.sensor_faults)
        elif not isinstance(episodes, WheelEpisodes) or episodes.n != self.n:
            raise UsageError(f"options['episodes'] must be {self.n} scftc-v2 episodes (WheelEpisodes)")
        self.plant = TESTBED.plant(episodes, self.backend)
        self.sensors = TESTBED.sensors(episodes)
        self.fuser = AttitudeFuser(self.n)
        self.prev_action = np.zeros((self.n, ACTION_DIM))
        self.k = 0
        return self._observe()

    def _observe(self) -> np.ndarray:
        """The sensors' observation of step ``k``; feeds the fuser (which must see every one)."""
        obs = self.sensors.observe(self.k, self.plant)
        heads, valid, gyro, _ = split_observation(obs)
        self.sigma_meas = self.fuser.update(heads, valid, gyro, V2.dt_s)
        self.gyro = gyro
        if self.include_prev_action:
            obs = np.concatenate((obs, self.prev_action), axis=1)
        return obs

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, np.ndarray]:
        """Apply ``action`` ``(n, 4)``; returns ``(obs (n, d) float64, reward (n,), truncated,
        true pointing error (n,) deg)``."""
        command = np.clip(checked_action(action, (self.n, ACTION_DIM)), -1.0, 1.0)
        error_deg = angle_deg_from_norm2(self.plant.step(self.k, command))
        self.prev_action = command
        self.k += 1
        obs = self._observe()
        return obs, shaped_reward(self.sigma_meas, self.gyro), self.k >= V2.steps, error_deg


def _episodes_option(options: dict[str, Any] | None) -> WheelEpisodes | None:
    return None if options is None else options.get("episodes")


class AttitudeFTCv2Env(gym.Env):
    """One ``scftc-v2`` episode per ``reset`` (see the module docstring).

    Args:
        split: ``train`` (default; the only split to learn on) or ``test``.
        fault_classes: actuator classes drawn uniformly per episode (default: all five).
        sensor_faults: sensor classes drawn uniformly per episode; ``None`` is healthy sensors
            (the default, ``(None,)``); a sensor fault rides on a ``sign`` fault, as in the benchmark.
        include_prev_action: append the previous (clipped) action to the observation.
        dtype: of the observations, ``np.float32`` (default) or ``np.float64``.
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(
        self,
        split: str = "train",
        fault_classes: tuple[str, ...] = DEFAULT_CLASSES,
        sensor_faults: tuple[str | None, ...] = DEFAULT_SENSORS,
        include_prev_action: bool = False,
        dtype: Any = np.float32,
    ) -> None:
        self._dtype = _check_dtype(dtype)
        self._batch = WheelBatch(1, split, tuple(fault_classes), tuple(sensor_faults), include_prev_action)
        self.observation_space = _observation_space(include_prev_action, self._dtype)
        self.action_space = _action_space()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        obs = self._batch.reset(self.np_random, _episodes_option(options))
        return obs[0].astype(self._dtype), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = checked_action(action, (ACTION_DIM,))
        obs, reward, truncated, error_deg = self._batch.step(action[None])
        info = {"pointing_error_deg": float(error_deg[0])}
        return obs[0].astype(self._dtype), float(reward[0]), False, bool(truncated), info


class AttitudeFTCv2VectorEnv(VectorEnv):
    """``num_envs`` ``scftc-v2`` episodes stepped as one call of the fused kernel (same-step
    autoreset); arguments as ``AttitudeFTCv2Env``, plus ``backend`` (``numpy`` or ``reference``)."""

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        num_envs: int = 64,
        split: str = "train",
        fault_classes: tuple[str, ...] = DEFAULT_CLASSES,
        sensor_faults: tuple[str | None, ...] = DEFAULT_SENSORS,
        include_prev_action: bool = False,
        dtype: Any = np.float32,
        backend: str = "numpy",
    ) -> None:
        self._dtype = _check_dtype(dtype)
        self._batch = WheelBatch(
            num_envs, split, tuple(fault_classes), tuple(sensor_faults), include_prev_action, backend
        )
        self.num_envs = num_envs
        self.single_observation_space = _observation_space(include_prev_action, self._dtype)
        self.single_action_space = _action_space()
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if isinstance(seed, list):
            seed = seed[0]
        if seed is not None:
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(seed)
        obs = self._batch.reset(self.np_random, _episodes_option(options))
        return obs.astype(self._dtype), {}

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        obs, reward, truncated, error_deg = self._batch.step(actions)
        info: dict[str, Any] = {"pointing_error_deg": error_deg}
        truncations = np.full(self.num_envs, truncated)
        if truncated:
            info["final_obs"], info["_final_obs"] = obs.astype(self._dtype), truncations.copy()
            obs = self._batch.reset(self.np_random)
        return obs.astype(self._dtype), reward, np.zeros(self.num_envs, dtype=bool), truncations, info
