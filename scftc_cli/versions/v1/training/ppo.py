"""Trainer of ``e2e_ppo``: sb3-contrib ``RecurrentPPO`` on ``scftc/AttitudeFTC-v1`` (train split).

The agent is trained from scratch on the vectorized environment (train-split ``sign``, ``gain``
and ``gain_bias`` faults, reward shaped on the measured error and rates; this version's ``envs.py``),
then its actor is exported to the plain torch ``RecurrentPolicy`` and saved as ``.npz`` weights,
which ``scftc eval`` runs with a numba kernel (``PolicyNet`` in ``baselines/policy.py``); that deployed
form is checked against sb3's own deterministic ``predict`` before it is saved.
Needs the optional extra ``rl`` (``gymnasium``, ``sb3-contrib``); evaluation needs neither them
nor torch.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from scftc_cli.baselines.params import save_params
from scftc_cli.baselines.policy import PolicyConfig, PolicyNet, save_policy
from scftc_cli.errors import ScftcError
from scftc_cli.training import TrainReport, TrainRequest, numpy_state, train_settled_rates
from scftc_cli.training.policy import RecurrentPolicy, policy_net
from scftc_cli.versions.v1.controllers.ppo import E2EPPO, OBS_SCALE
from scftc_cli.versions.v1.spec import V1

CLASSES = ("sign", "gain", "gain_bias")


@dataclass(frozen=True)
class PPOBudget:
    """How much experience one run collects, and PPO's settings."""

    total_timesteps: int
    n_envs: int = 32
    n_steps: int = 400  # one full episode per env per rollout
    batch_size: int = 1600
    n_epochs: int = 10
    learning_rate: float = 3e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    log_std_init: float = -0.5
    eval_faults: int = 50
    eval_seeds: int = 10


BUDGETS: dict[str, PPOBudget] = {
    "quick": PPOBudget(
        total_timesteps=2 * 8 * 400, n_envs=8, batch_size=800, n_epochs=2, eval_faults=10, eval_seeds=2
    ),
    "full": PPOBudget(total_timesteps=125 * 32 * 400),  # 125 rollouts, 1.6M steps: 51 min measured on 2 cores
}


def _sb3_vec_env(num_envs: int, seed: int) -> Any:
    """``AttitudeFTCVectorEnv`` behind stable-baselines3's ``VecEnv`` interface, inputs scaled."""
    from gymnasium import spaces
    from stable_baselines3.common.vec_env import VecEnv

    from scftc_cli.versions.v1.envs import AttitudeFTCVectorEnv

    scale = np.asarray(OBS_SCALE, dtype=np.float32)

    class Adapter(VecEnv):
        def __init__(self) -> None:
            # per_episode: the random stream the committed weights were trained on
            self.venv = AttitudeFTCVectorEnv(
                num_envs, "train", CLASSES, include_prev_action=True, sampler="per_episode"
            )
            space = self.venv.single_observation_space
            assert isinstance(space, spaces.Box)
            obs_space = spaces.Box(space.low * scale, space.high * scale, dtype=np.float32)
            super().__init__(num_envs, obs_space, self.venv.single_action_space)
            self.seeded = False

        def reset(self) -> np.ndarray:
            obs, _ = self.venv.reset(seed=None if self.seeded else seed)
            self.seeded = True
            return obs * scale

        def step_async(self, actions: np.ndarray) -> None:
            self.actions = actions

        def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
            obs, reward, terminated, truncated, info = self.venv.step(self.actions)
            dones = terminated | truncated
            infos: list[dict] = [{} for _ in range(num_envs)]
            if dones.any():
                for i in np.flatnonzero(dones):
                    infos[i]["terminal_observation"] = info["final_obs"][i] * scale
                    infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            return obs * scale, reward.astype(np.float32), dones, infos

        def close(self) -> None:
            pass

        def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
            return [getattr(self.venv, attr_name)] * num_envs

        def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
            setattr(self.venv, attr_name, value)

        def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list:
            return [getattr(self.venv, method_name)(*args, **kwargs)] * num_envs

        def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
            return [False] * num_envs

    return Adapter()


def export_policy(model: Any, config: PolicyConfig) -> RecurrentPolicy:
    """Copy the actor of a trained ``RecurrentPPO`` into a plain ``RecurrentPolicy``."""
    sb3 = model.policy
    policy = RecurrentPolicy(config, len(OBS_SCALE), V1.action_dim)
    policy.lstm.load_state_dict(sb3.lstm_actor.state_dict())
    policy.mlp.load_state_dict(sb3.mlp_extractor.policy_net.state_dict())
    policy.action.load_state_dict(sb3.action_net.state_dict())
    return policy.eval()


def check_export(model: Any, net: PolicyNet, steps: int = 50) -> float:
    """Largest difference between sb3's deterministic ``predict`` and the deployed export, over
    ``steps`` steps of a few train episodes (both fed the same observations)."""
    env = _sb3_vec_env(4, seed=12345)
    obs, state = env.reset(), None
    starts = np.ones(4, dtype=bool)
    mine = net.start(4)
    worst = 0.0
    for _ in range(steps):
        action, state = model.predict(obs, state=state, episode_start=starts, deterministic=True)
        mean = net.step(obs.astype(np.float64), mine)
        worst = max(worst, float(np.max(np.abs(np.clip(mean, -1, 1) - action))))
        obs, _, done, _ = env.step(action)
        starts = done
    return worst


def settled_rate(net: PolicyNet, n_faults: int, n_seeds: int) -> float:
    """Mean settled rate over the pinned *train* cells of ``CLASSES``."""
    rates = train_settled_rates(lambda: E2EPPO(net=net), CLASSES, n_faults, n_seeds, V1)
    return float(np.mean(list(rates.values())))


def train_e2e_ppo(request: TrainRequest) -> TrainReport:
    """``scftc train --controller e2e_ppo``: RecurrentPPO from scratch on the train split."""
    try:
        from sb3_contrib import RecurrentPPO
        from stable_baselines3.common.callbacks import BaseCallback
        from stable_baselines3.common.logger import Logger
        from stable_baselines3.common.vec_env import VecNormalize
    except ImportError as err:  # pragma: no cover - depends on the installed extras
        raise ScftcError("training e2e_ppo needs the `rl` extra: pip install 'scftc[rl]'") from err

    budget = BUDGETS[request.budget]
    config = PolicyConfig()
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    start = time.monotonic()
    returns: list[float] = []

    class Progress(BaseCallback):
        """Mean raw (unnormalized) episode return of each rollout: one rollout is one episode."""

        raw = 0.0

        def _on_step(self) -> bool:
            self.raw += float(np.mean(self.training_env.get_original_reward()))  # type: ignore[attr-defined]
            return True

        def _on_rollout_end(self) -> None:
            returns.append(self.raw)
            self.raw = 0.0
            done = self.model.num_timesteps / budget.total_timesteps
            request.on_progress(
                min(done, 1.0), f"{self.model.num_timesteps} steps, episode return {returns[-1]:.1f}"
            )

    try:
        # Returns are scaled to unit variance for the critic (training only; the policy's input
        # is the fixed-scaled observation, so the export needs no statistics).
        env = VecNormalize(
            _sb3_vec_env(budget.n_envs, request.seed), norm_obs=False, norm_reward=True, gamma=budget.gamma
        )
        model = RecurrentPPO(
            "MlpLstmPolicy",
            env,
            n_steps=budget.n_steps,
            batch_size=budget.batch_size,
            n_epochs=budget.n_epochs,
            learning_rate=budget.learning_rate,
            gamma=budget.gamma,
            gae_lambda=budget.gae_lambda,
            clip_range=budget.clip_range,
            ent_coef=budget.ent_coef,
            seed=request.seed,
            device="cpu",
            verbose=0,
            policy_kwargs={
                "lstm_hidden_size": config.lstm_hidden,
                "n_lstm_layers": 1,
                "net_arch": {"pi": list(config.net_arch), "vf": list(config.net_arch)},
                "log_std_init": budget.log_std_init,
            },
        )
        model.set_logger(Logger(folder=None, output_formats=[]))  # sb3's default makes a /tmp folder
        model.learn(total_timesteps=budget.total_timesteps, callback=Progress())
        policy = export_policy(model, config)
        net = policy_net(policy, config)
        mismatch = check_export(model, net)
        if mismatch > 1e-5:
            raise ScftcError(f"exported e2e_ppo policy disagrees with sb3 by {mismatch:.2e}")
        request.on_progress(1.0, "scoring on the pinned train cells")
        train_rate = settled_rate(net, budget.eval_faults, budget.eval_seeds)
    finally:
        torch.set_num_threads(threads)
    out = request.artifact_out()
    save_policy(numpy_state(policy), config, out)
    wall_s = time.monotonic() - start
    provenance = request.provenance(
        train_rate,
        f"sb3-contrib RecurrentPPO (MlpLstmPolicy), {model.num_timesteps} env steps on train "
        f"classes {list(CLASSES)}; wall {wall_s:.0f} s on CPU (1 thread); "
        "train_settled_rate = mean settled rate over the pinned train cells of those classes",
    )
    params = {
        "config": config.to_dict(),
        "budget": asdict(budget),
        "reward_normalization": True,
        "rollout_mean_episode_return": [round(r, 3) for r in returns[:: max(1, len(returns) // 50)]],
        "final_rollout_return": round(returns[-1], 3) if returns else None,
        "export_max_abs_diff": mismatch,
        "weights_file": Path(out).name,
    }
    save_params("e2e_ppo", params, provenance, Path(out).with_suffix(".yaml"))
    return TrainReport("e2e_ppo", Path(out), train_rate, {"wall_s": wall_s, "returns": returns})
