"""``scftc/AttitudeFTC-v1``: the benchmark's plant and fault taxonomy as a gymnasium environment.

An episode is one benchmark episode (docs/benchmark.md): a fault drawn from the chosen split and
classes, ``sigma0`` uniform in [-0.5, 0.5]^3, ``w0`` uniform in [-0.02, 0.02]^3 rad/s, 400 steps of
0.5 s, then truncation. The agent observes only ``obs = [sigma_meas, w_meas]`` (optionally with
its previous action) and commands three normalized torques in [-1, 1]; the fault is never part
of the observation or of ``info``. The reward is shaped on the *measured* pointing error and
rates (the benchmark scores the true state, which only ``info["pointing_error_deg"]`` reports,
for logging):

    r = -e_meas_deg / 180 - |w_meas| + 0.5 exp(-e_meas_deg / 1 deg)

``AttitudeFTCEnv`` is the single-episode ``gymnasium.Env`` (passes ``check_env``);
``AttitudeFTCVectorEnv`` steps ``num_envs`` episodes as one call of the benchmark's fused kernel
(``backend="numpy"``, bit-identical to the ``reference`` numpy plant; same-step autoreset: all
episodes share the fixed horizon, so they reset together and the last observation is in
``info["final_obs"]``). Train only on the ``train`` split; the
``test`` split exists here for evaluation, never for tuning.
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
from scftc_cli.versions.v1.sim.faults import sample_episodes, sample_episodes_batch
from scftc_cli.versions.v1.sim.testbed import TESTBED
from scftc_cli.versions.v1.spec import V1

ENV_ID = "scftc/AttitudeFTC-v1"
SAMPLERS = {"batch": sample_episodes_batch, "per_episode": sample_episodes}
"""How a reset draws its episodes: ``batch`` (whole arrays, fast) or ``per_episode`` (one fault at
a time, the stream the committed e2e_ppo weights were trained on). Same distribution."""
DEFAULT_CLASSES = ("sign", "gain", "gain_bias")
# A bound no episode can reach: |H| <= sqrt(3) (2.0 + 0.3) tau_max * 200 s ~ 160 N m s over a whole
# episode, so |w| <= 160 / (0.7 * 6 kg m^2) ~ 38 rad/s whatever the controller does.
OMEGA_BOUND_RAD_S = 50.0


def shaped_reward(obs: np.ndarray) -> np.ndarray:
    """``(n,)`` reward of the measured post-step observations ``obs`` ``(n, 6)``."""
    error_deg = principal_angle_deg(obs[:, :3])
    rate = np.linalg.norm(obs[:, 3:6], axis=1)
    return -error_deg / 180.0 - rate + 0.5 * np.exp(-error_deg / 1.0)


def _observation_space(include_prev_action: bool) -> spaces.Box:
    low = [-1.0] * 3 + [-OMEGA_BOUND_RAD_S] * 3 + ([-1.0] * 3 if include_prev_action else [])
    low_arr = np.array(low, dtype=np.float32)
    high_arr = -low_arr
    return spaces.Box(low_arr, high_arr, dtype=np.float32)


class _Batch:
    """``n`` benchmark episodes stepped together on the fused kernel; the core of both environments."""

    def __init__(
        self,
        n: int,
        split: str,
        fault_classes: tuple[str, ...],
        include_prev_action: bool,
        sampler: str,
        backend: str = "numpy",
    ) -> None:
        if not fault_classes:
            raise UsageError("fault_classes must name at least one class")
        for c in fault_classes:
            V1.check_cell(split, c)
        if sampler not in SAMPLERS:
            raise UsageError(f"sampler must be one of {', '.join(SAMPLERS)}, got {sampler!r}")
        self.n, self.split, self.fault_classes = n, split, tuple(fault_classes)
        self.include_prev_action = include_prev_action
        self.sample = SAMPLERS[sampler]
        self.backend = backend
        self.k = 0

    def reset(self, rng: np.random.Generator) -> np.ndarray:
        """Draw ``n`` fresh episodes from ``rng``; returns the first observations ``(n, d)``."""
        episodes = self.sample(rng, self.n, self.split, self.fault_classes)
        self.plant = TESTBED.plant(episodes, self.backend)
        self.prev_action = np.zeros((self.n, 3))
        self.k = 0
        return self._obs()

    def _obs(self) -> np.ndarray:
        states = self.plant.states()
        cols = [states["sigma"], states["omega_rad_s"]] + (
            [self.prev_action] if self.include_prev_action else []
        )
        return np.concatenate(cols, axis=1).astype(np.float32)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, np.ndarray]:
        """Apply ``action`` ``(n, 3)``; returns ``(obs (n, d), reward (n,), truncated, true error)``."""
        command = np.clip(np.asarray(action, dtype=float).reshape(self.n, 3), -1.0, 1.0)
        sigma_norm2 = self.plant.step(self.k, command)
        self.prev_action = command
        self.k += 1
        obs = self._obs()
        return obs, shaped_reward(obs), self.k >= V1.steps, angle_deg_from_norm2(sigma_norm2)


class AttitudeFTCEnv(gym.Env):
    """One benchmark episode per ``reset`` (see the module docstring).

    Args:
        split: ``train`` (default; the only split to learn on) or ``test``.
        fault_classes: actuator classes drawn uniformly per episode.
        include_prev_action: append the previous (clipped) action to the observation.
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(
        self,
        split: str = "train",
        fault_classes: tuple[str, ...] = DEFAULT_CLASSES,
        include_prev_action: bool = False,
    ) -> None:
        self._batch = _Batch(1, split, tuple(fault_classes), include_prev_action, "per_episode")
        self.observation_space = _observation_space(include_prev_action)
        self.action_space = spaces.Box(-1.0, 1.0, (3,), dtype=np.float32)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        return self._batch.reset(self.np_random)[0], {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, truncated, error_deg = self._batch.step(np.asarray(action)[None, :])
        return obs[0], float(reward[0]), False, bool(truncated), {"pointing_error_deg": float(error_deg[0])}


class AttitudeFTCVectorEnv(VectorEnv):
    """``num_envs`` episodes stepped as one array operation (same-step autoreset)."""

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        num_envs: int = 64,
        split: str = "train",
        fault_classes: tuple[str, ...] = DEFAULT_CLASSES,
        include_prev_action: bool = False,
        sampler: str = "batch",
        backend: str = "numpy",
    ) -> None:
        if num_envs < 1:
            raise UsageError("num_envs must be at least 1")
        self.num_envs = num_envs
        self._batch = _Batch(num_envs, split, tuple(fault_classes), include_prev_action, sampler, backend)
        self.single_observation_space = _observation_space(include_prev_action)
        self.single_action_space = spaces.Box(-1.0, 1.0, (3,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if isinstance(seed, list):
            seed = seed[0]
        if seed is not None:
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(seed)
        return self._batch.reset(self.np_random), {}

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        obs, reward, truncated, error_deg = self._batch.step(actions)
        info: dict[str, Any] = {"pointing_error_deg": error_deg}
        truncations = np.full(self.num_envs, truncated)
        if truncated:
            info["final_obs"], info["_final_obs"] = obs, truncations.copy()
            obs = self._batch.reset(self.np_random)
        return obs, reward.astype(np.float64), np.zeros(self.num_envs, dtype=bool), truncations, info
