"""What the gymnasium environments of the versions with noisy sensors (a reaction-wheel plant read
through star-tracker heads and a gyro) share: a batch of benchmark episodes flown on the
version's own testbed (``EpisodeBatch``), the single-episode ``gymnasium.Env`` and the vector
environment around it, the shaped reward on the measured state and the checks of actions and
dtypes. A version says how it draws fresh episodes,
what its measured error is and what its observations hold (``EpisodeBatch``'s abstract parts);
everything else is here, once. Imported only by the versions' environment modules (so
``import scftc_cli`` never imports gymnasium).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import VectorEnv
from gymnasium.vector.utils import batch_space
from gymnasium.vector.vector_env import AutoresetMode

from scftc_cli.errors import UsageError
from scftc_cli.evaluate import Cell, check_held_out_open
from scftc_cli.sim.episodes import Episodes
from scftc_cli.sim.mrp import angle_deg_from_norm2, principal_angle_deg
from scftc_cli.sim.testbed import Testbed
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.versions.v2.controllers.law import AttitudeFuser, split_observation


def shaped_reward(error_mrp: np.ndarray, gyro_rad_s: np.ndarray) -> np.ndarray:
    """``(n,)`` reward of the measured pointing error ``(n, 3)`` MRP and the gyro reading ``(n, 3)``
    rad/s: ``-e_deg / 180 - |w| + 0.5 exp(-e_deg / 1 deg)`` (``scftc/AttitudeFTC-v1``'s shape)."""
    error_deg = principal_angle_deg(error_mrp)
    rate = np.linalg.norm(gyro_rad_s, axis=1)
    return -error_deg / 180.0 - rate + 0.5 * np.exp(-error_deg / 1.0)


def checked_action(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``action`` as float64 (a float32 action converts exactly); a wrong shape or a non-finite
    value is a ``UsageError`` that names the expected shape."""
    action = np.asarray(action)
    if action.shape != shape:
        raise UsageError(f"action must have shape {shape} (one command per actuator), got {action.shape}")
    if not np.all(np.isfinite(action)):
        raise UsageError("action must be finite, got NaN or inf")
    return action.astype(np.float64)


def check_dtype(dtype: Any) -> type:
    """The observations' scalar type: float32 or float64, else a ``UsageError``."""
    chosen = np.dtype(dtype).type
    if chosen not in (np.float32, np.float64):
        raise UsageError(f"dtype must be float32 or float64, got {np.dtype(dtype).name}")
    return chosen


class EpisodeBatch(ABC):
    """``n`` episodes of one version flown together: its plant (the fused kernel by default), its
    sensors, and the fuser that measures the reward; the core of both environments.

    Args:
        n: episodes per batch.
        split, fault_classes, sensor_faults: what ``reset`` draws (``None`` in ``sensor_faults``:
            healthy sensors; ``None`` for either tuple: the version's defaults); checked here, so a
            bad name fails at construction.
        include_prev_action: append the previous clipped action to the observation.
        backend: ``numpy`` (fused, default) or ``reference``.
    """

    spec: ClassVar[BenchmarkSpec]
    testbed: ClassVar[Testbed]
    episodes_type: ClassVar[type[Episodes]]
    default_classes: ClassVar[tuple[str, ...]]
    default_sensors: ClassVar[tuple[str | None, ...]] = (None,)

    def __init__(
        self,
        n: int,
        split: str = "train",
        fault_classes: tuple[str, ...] | None = None,
        sensor_faults: tuple[str | None, ...] | None = None,
        include_prev_action: bool = False,
        backend: str = "numpy",
    ) -> None:
        fault_classes = self.default_classes if fault_classes is None else tuple(fault_classes)
        sensor_faults = self.default_sensors if sensor_faults is None else tuple(sensor_faults)
        if n < 1:
            raise UsageError("num_envs must be at least 1")
        if not fault_classes or not sensor_faults:
            raise UsageError("name at least one fault class and one sensor class (None: healthy)")
        for c in fault_classes:
            self.spec.check_cell(split, c)
        for s in sensor_faults:
            if s is not None:
                self.spec.check_cell(split, self.spec.sensor_base_class, s)
        if backend not in ("numpy", "reference"):
            raise UsageError(f"backend must be numpy or reference, got {backend!r}")
        # an agent in training is a deployable controller: a draft's held-out split stays closed to it
        check_held_out_open(self.spec, [Cell(split, c) for c in fault_classes], privileged=False)
        self.n, self.split = n, split
        self.fault_classes, self.sensor_faults = fault_classes, sensor_faults
        self.include_prev_action = include_prev_action
        self.backend = backend
        self.k = 0

    @classmethod
    @abstractmethod
    def observation_space(cls, include_prev_action: bool, dtype: type) -> spaces.Box:
        """One episode's observation space (bounds no episode reaches)."""

    @abstractmethod
    def draw(self, rng: np.random.Generator) -> Episodes:
        """``n`` fresh episodes of the batch's split and classes, from ``rng``."""

    @abstractmethod
    def measured_error(self, obs: np.ndarray, fused_sigma: np.ndarray) -> np.ndarray:
        """The measured pointing error ``(n, 3)`` MRP the reward reads, from the raw observation
        ``(n, obs_dim)`` and the fused attitude ``(n, 3)``."""

    def reset(self, rng: np.random.Generator, episodes: Episodes | None = None) -> np.ndarray:
        """Draw ``n`` fresh episodes from ``rng`` (or fly ``episodes``); the first observations
        ``(n, obs_dim [+ action_dim])`` float64."""
        if episodes is None:
            episodes = self.draw(rng)
        elif not isinstance(episodes, self.episodes_type) or episodes.n != self.n:
            raise UsageError(
                f"options['episodes'] must be {self.n} {self.spec.version} episodes "
                f"({self.episodes_type.__name__})"
            )
        self.episodes = episodes  # what is flown (a residual policy's base law reads their context)
        self.plant = self.testbed.plant(episodes, self.backend)
        self.sensors = self.testbed.sensors(episodes)
        self.fuser = AttitudeFuser(self.n)
        self.prev_action = np.zeros((self.n, self.spec.action_dim))
        self.k = 0
        return self._observe()

    def _observe(self) -> np.ndarray:
        """The sensors' observation of step ``k``; feeds the fuser (which must see every one)."""
        obs = self.sensors.observe(self.k, self.plant)
        heads, valid, self.gyro, _ = split_observation(obs)  # v2's 19 readings lead every observation
        self.error_meas = self.measured_error(obs, self.fuser.update(heads, valid, self.gyro, self.spec.dt_s))
        if self.include_prev_action:
            obs = np.concatenate((obs, self.prev_action), axis=1)
        return obs

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, np.ndarray]:
        """Apply ``action`` ``(n, action_dim)``; returns ``(obs (n, d) float64, reward (n,),
        truncated, true pointing error (n,) deg)``."""
        command = np.clip(checked_action(action, (self.n, self.spec.action_dim)), -1.0, 1.0)
        error_deg = angle_deg_from_norm2(self.plant.step(self.k, command))
        self.prev_action = command
        self.k += 1
        obs = self._observe()
        return obs, shaped_reward(self.error_meas, self.gyro), self.k >= self.spec.steps, error_deg


def _episodes_option(options: dict[str, Any] | None) -> Episodes | None:
    return None if options is None else options.get("episodes")


def _action_space(action_dim: int) -> spaces.Box:
    return spaces.Box(-1.0, 1.0, (action_dim,), dtype=np.float32)


class BatchEnv(gym.Env):
    """One episode per ``reset``, flown by a one-episode ``batch_type``.

    Args:
        split: ``train`` (default; the only split to learn on) or ``test``.
        fault_classes: actuator classes drawn uniformly per episode (default: the version's).
        sensor_faults: sensor classes drawn uniformly per episode; ``None`` is healthy sensors
            (the default, ``(None,)``); a sensor fault rides on a ``sign`` fault, as in the benchmark.
        include_prev_action: append the previous (clipped) action to the observation.
        dtype: of the observations, ``np.float32`` (default) or ``np.float64``.
    """

    metadata: dict[str, Any] = {"render_modes": []}
    batch_type: ClassVar[type[EpisodeBatch]]

    def __init__(
        self,
        split: str = "train",
        fault_classes: tuple[str, ...] | None = None,
        sensor_faults: tuple[str | None, ...] | None = None,
        include_prev_action: bool = False,
        dtype: Any = np.float32,
    ) -> None:
        self._dtype = check_dtype(dtype)
        self._batch = self.batch_type(1, split, fault_classes, sensor_faults, include_prev_action)
        self.observation_space = self.batch_type.observation_space(include_prev_action, self._dtype)
        self.action_space = _action_space(self.batch_type.spec.action_dim)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        obs = self._batch.reset(self.np_random, _episodes_option(options))
        return obs[0].astype(self._dtype), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = checked_action(action, (self.batch_type.spec.action_dim,))
        obs, reward, truncated, error_deg = self._batch.step(action[None])
        info = {"pointing_error_deg": float(error_deg[0])}
        return obs[0].astype(self._dtype), float(reward[0]), False, bool(truncated), info


class BatchVectorEnv(VectorEnv):
    """``num_envs`` episodes stepped as one call of the fused kernel (same-step autoreset: every
    episode shares the fixed horizon, so they reset together and the last observation is in
    ``info["final_obs"]``); arguments as ``BatchEnv``, plus ``backend`` (``numpy`` or
    ``reference``)."""

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}
    batch_type: ClassVar[type[EpisodeBatch]]

    def __init__(
        self,
        num_envs: int = 64,
        split: str = "train",
        fault_classes: tuple[str, ...] | None = None,
        sensor_faults: tuple[str | None, ...] | None = None,
        include_prev_action: bool = False,
        dtype: Any = np.float32,
        backend: str = "numpy",
    ) -> None:
        self._dtype = check_dtype(dtype)
        self._batch = self.batch_type(
            num_envs, split, fault_classes, sensor_faults, include_prev_action, backend
        )
        self.num_envs = num_envs
        self.single_observation_space = self.batch_type.observation_space(include_prev_action, self._dtype)
        self.single_action_space = _action_space(self.batch_type.spec.action_dim)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)

    @property
    def episodes(self) -> Episodes:
        """The episodes flown now (drawn at the last reset or the same-step autoreset). For a
        trainer's own law inside the step (a residual policy's base reads their public context),
        never an agent's input: they hold the faults."""
        return self._batch.episodes

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
