"""Trainers of ``e2e_ppo`` and ``residual_ppo`` on ``scftc-v4``.

``e2e_ppo``: v3's run (``versions/v3/training/ppo.py``: the batched
recurrent PPO of ``training/recurrent_ppo.py`` from scratch, v3's budgets) on
``scftc/AttitudeFTC-v4``, every actuator class of v4's train split (no sensor class drawn;
``compound`` episodes carry their companion sensor fault, as in the benchmark).

``residual_ppo``: the same PPO on the same split, through ``ResidualVectorEnv``: the environment
steps ``pd``'s command plus the policy's scaled correction, and the policy reads the base command
beside the readings (``controllers/ppo.py``, ``ResidualPPO``). Its reward is its own, on the
measured error ``e`` (the base law's fused attitude to the current target) and the correction
``c`` in [-1, 1]:

    r = exp(-e_deg / settled_deg) + exp(-e_deg / (10 settled_deg)) - CORRECTION_COST |c|^2,

which pays for pointing at the settled gate's scale (and leads there from ten times it) and is
flat during a slew. The
environment's shaped reward (``scftc/AttitudeFTC-v3``'s, ``-e/180 - |w| + ...``) is dominated by
the slews, where the base flies at its rate cap: the first full run on it learned to slew harder
and lost every episode (train settled 0.0 at every checkpoint). Exploration starts small
(log-std -2.0: a correction noise of about 0.03 of an actuator's limit) with a lower learning
rate, and the untrained policy (``pd`` to 5 % of its command) is a checkpoint candidate
(``eval_start``). The ``full`` budget is 40 rollouts of 64 whole episodes (6.1 M env steps, a
quarter of ``e2e_ppo``'s); what a full run takes is in its provenance.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from scftc_cli.baselines.policy import PolicyNet
from scftc_cli.errors import ScftcError
from scftc_cli.protocol import Controller
from scftc_cli.sim.mrp import principal_angle_deg
from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.training.recurrent_ppo import PPOBudget, PPOPlan, train_recurrent_ppo
from scftc_cli.versions.v3.controllers.analytic import PD
from scftc_cli.versions.v3.controllers.law import TARGET, attitude_error
from scftc_cli.versions.v3.sim.faults import AgileEpisodes
from scftc_cli.versions.v3.sim.testbed import public_context
from scftc_cli.versions.v3.training import ppo as v3
from scftc_cli.versions.v4.controllers.ppo import (
    E2EPPO,
    OBS_SCALE,
    RESIDUAL_OBS_SCALE,
    RESIDUAL_SCALE,
    ResidualPPO,
)
from scftc_cli.versions.v4.spec import V4

CLASSES = V4.fault_classes
BUDGETS = dict(v3.BUDGETS)
"""v3's budgets (a copy: changing v4's never changes v3's)."""


def vector_env() -> type:
    """``scftc/AttitudeFTC-v4``'s vector environment class (gymnasium is the ``rl`` extra's)."""
    try:
        from scftc_cli.versions.v4.envs import AttitudeFTCv4VectorEnv
    except ImportError as err:  # pragma: no cover - depends on the installed extras
        raise ScftcError("training a policy needs the `rl` extra: pip install 'scftc[rl]'") from err
    return AttitudeFTCv4VectorEnv


def _train(
    request: TrainRequest,
    budget: PPOBudget,
    make_env: Callable[..., Any],
    obs_scale: tuple[float, ...],
    deployed: Callable[[PolicyNet], Controller],
) -> TrainReport:
    """The shared recurrent PPO on v4's train split, every actuator class."""
    plan = PPOPlan(spec=V4, make_env=make_env, classes=CLASSES, obs_scale=obs_scale, deployed=deployed)
    return train_recurrent_ppo(request, budget, plan)


def train_e2e_ppo(request: TrainRequest) -> TrainReport:
    """``scftc train --benchmark scftc-v4 --controller e2e_ppo``: PPO from scratch on the train split."""
    return _train(request, BUDGETS[request.budget], vector_env(), OBS_SCALE, lambda net: E2EPPO(net=net))


RESIDUAL_BUDGETS: dict[str, PPOBudget] = {
    "quick": PPOBudget(
        rollouts=2, n_envs=8, minibatch_envs=4, n_epochs=1, eval_every=2, eval_faults=1, eval_seeds=1,
        log_std_init=-2.0, learning_rate=1e-4, eval_start=True,
    ),
    "full": PPOBudget(
        rollouts=40, n_envs=64, minibatch_envs=32, eval_every=8, log_std_init=-2.0, learning_rate=1e-4,
        eval_start=True,
    ),
}  # fmt: skip
CORRECTION_COST = 0.01
"""The reward's price of a correction at an actuator's full residual range, per step."""


class ResidualVectorEnv:
    """``scftc/AttitudeFTC-v4``'s vector environment (float64 readings, as a controller gets them)
    with ``pd``'s law inside the step: the observation is the readings and the base command
    ``(n, 26 + 7)`` (float32), the action the policy's correction ``(n, 7)``, and the environment
    flies ``clip(base + RESIDUAL_SCALE * clip(correction))`` (``ResidualPPO``'s command). The base
    law is reset with the episodes (every ``reset`` and the same-step autoreset)."""

    def __init__(self, n: int, split: str, classes: tuple[str, ...]) -> None:
        self.env = vector_env()(n, split, classes, dtype=np.float64)
        self.n = n

    def _start(self, readings: np.ndarray) -> np.ndarray:
        self.base = PD()
        episodes = self.env.episodes
        assert isinstance(episodes, AgileEpisodes)
        self.base.reset(self.n, public_context(episodes, spec=V4))
        return self._observe(readings)

    def _observe(self, readings: np.ndarray) -> np.ndarray:
        self.base_command = self.base.act(readings)
        return np.concatenate((readings, self.base_command), axis=1).astype(np.float32)

    def reset(self, *, seed: int | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        readings, info = self.env.reset(seed=seed)
        return self._start(readings), info

    def step(
        self, correction: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        bounded = np.clip(correction, -1.0, 1.0)
        command = np.clip(self.base_command + RESIDUAL_SCALE * bounded, -1.0, 1.0)
        readings, _, terminated, truncated, info = self.env.step(command)
        cost = CORRECTION_COST * (bounded * bounded).sum(axis=1)
        if truncated.all():  # the episodes ended and the inner environment drew the next ones
            info["final_obs"] = self._observe(info["final_obs"])
            reward = self._pointing(info["final_obs"]) - cost
            return self._start(readings), reward, terminated, truncated, info
        observation = self._observe(readings)
        return observation, self._pointing(observation) - cost, terminated, truncated, info

    def _pointing(self, observation: np.ndarray) -> np.ndarray:
        """``exp(-e_deg / settled_deg) + exp(-e_deg / (10 settled_deg))`` ``(n,)`` for the measured
        error ``e`` of the readings the base law has just fused (module docstring)."""
        target = observation[:, TARGET].astype(np.float64)
        error = principal_angle_deg(attitude_error(self.base.fuser.sigma, target))
        scale = V4.gates.settled_deg
        return np.exp(-error / scale) + np.exp(-error / (10.0 * scale))


def train_residual_ppo(request: TrainRequest) -> TrainReport:
    """``scftc train --benchmark scftc-v4 --controller residual_ppo``: PPO on ``pd``'s correction."""
    budget = RESIDUAL_BUDGETS[request.budget]
    return _train(request, budget, ResidualVectorEnv, RESIDUAL_OBS_SCALE, lambda net: ResidualPPO(net=net))
