"""Batched recurrent PPO for a version's ``e2e_ppo`` (its ``training/ppo.py`` gives the plan): one
loop, each version's environment, classes and observation scaling (``PPOPlan``).

PPO (Schulman et al. 2017, arXiv 1707.06347) with the clipped surrogate, GAE (lambda 0.95), the
learning rate annealed linearly to zero over the run, returns scaled to unit variance for the
critic (as sb3's ``VecNormalize``), advantages normalized per minibatch and a state-independent
Gaussian log-std; the actor and the critic each have their own LSTM (sb3-contrib
``RecurrentPPO``'s default layout). Written here rather than run through sb3-contrib because the
environment steps a whole batch as one call of the fused kernel: a rollout is ``n_envs`` complete
episodes collected in lockstep, and each epoch runs the LSTMs over whole episodes
(backpropagation through every step) in a few fused calls, about twenty times sb3-contrib's
throughput on the same machine.

The environment draws train-split episodes of every actuator class (healthy sensors); the reward
is the environment's, shaped on the *measured* error and rates. Every ``eval_every`` rollouts the
deterministic actor (the numba kernel, as deployed) flies a few pinned *train* episodes of each
class; the checkpoint kept is the best there (settled rate, then the smaller median final error;
with ``eval_start`` the untrained policy is a candidate too, so a residual policy is never kept
worse than its base law on those episodes).
Nothing here sees the test split. Deterministic for a seed (one torch thread, seeded generators).
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from scftc_cli.baselines.params import save_params
from scftc_cli.baselines.policy import PolicyConfig, PolicyNet, save_policy
from scftc_cli.errors import ScftcError
from scftc_cli.evaluate import Cell, evaluate_cells
from scftc_cli.protocol import Controller
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.training import TrainReport, TrainRequest, numpy_state
from scftc_cli.training.policy import RecurrentPolicy, policy_net


class Critic(nn.Module):
    """The value function: its own LSTM, one tanh layer, a linear head; ``(T, B, inputs)`` -> ``(T, B)``."""

    def __init__(self, config: PolicyConfig, inputs: int) -> None:
        super().__init__()
        self.lstm = nn.LSTM(inputs, config.lstm_hidden)
        width = config.net_arch[-1] if config.net_arch else config.lstm_hidden
        self.mlp = nn.Sequential(nn.Linear(config.lstm_hidden, width), nn.Tanh())
        self.value = nn.Linear(width, 1)

    def forward(
        self, x: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor] | None = None
    ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        y, state = self.lstm(x, state)
        return self.value(self.mlp(y))[..., 0], state


class ActorCritic(nn.Module):
    """Actor, critic and the Gaussian's log-std (one per action)."""

    def __init__(self, config: PolicyConfig, log_std_init: float, inputs: int, actions: int) -> None:
        super().__init__()
        self.actor = RecurrentPolicy(config, inputs, actions)
        self.critic = Critic(config, inputs)
        self.log_std = nn.Parameter(torch.full((actions,), log_std_init))
        # sb3's initialization: orthogonal, small action head, unit value head
        for module in self.modules():
            if isinstance(module, nn.Linear):
                nn.init.orthogonal_(module.weight, gain=float(np.sqrt(2.0)))
                nn.init.zeros_(module.bias)
        nn.init.orthogonal_(self.actor.action.weight, gain=0.01)
        nn.init.orthogonal_(self.critic.value.weight, gain=1.0)


@dataclass(frozen=True)
class PPOBudget:
    """How much experience one run collects, and PPO's settings."""

    rollouts: int  # each: n_envs complete episodes
    n_envs: int = 128
    minibatch_envs: int = 64  # episodes per gradient step (whole sequences)
    n_epochs: int = 5
    learning_rate: float = 3e-4  # at the start; annealed linearly to zero
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    log_std_init: float = -0.5
    eval_every: int = 20  # rollouts between checkpoint evaluations
    eval_start: bool = False  # also score the untrained policy as a checkpoint (a residual's start)
    eval_faults: int = 10  # pinned train episodes per class of a checkpoint evaluation (x eval_seeds)
    eval_seeds: int = 2
    lstm_hidden: int = 64
    net_arch: tuple[int, ...] = (64,)

    def env_steps(self, steps: int) -> int:
        """Env steps of the run, for episodes of ``steps`` steps."""
        return self.rollouts * self.n_envs * steps


class ReturnScale:
    """Running variance of the discounted return of every environment (sb3's ``VecNormalize``
    reward scaling): rewards are divided by its square root for the critic."""

    def __init__(self, n: int, gamma: float) -> None:
        self.gamma, self.ret = gamma, np.zeros(n)
        self.mean, self.var, self.count = 0.0, 1.0, 1e-4

    def __call__(self, reward: np.ndarray) -> np.ndarray:
        self.ret = self.ret * self.gamma + reward
        batch_mean, batch_var, n = float(self.ret.mean()), float(self.ret.var()), len(self.ret)
        delta, total = batch_mean - self.mean, self.count + n
        self.mean += delta * n / total
        self.var = (self.var * self.count + batch_var * n + delta * delta * self.count * n / total) / total
        self.count = total
        return reward / np.sqrt(self.var + 1e-8)

    def episode_end(self) -> None:
        self.ret[:] = 0.0


def gae(
    rewards: np.ndarray, values: np.ndarray, last_value: np.ndarray, gamma: float, lam: float
) -> np.ndarray:
    """Advantages ``(T, n)`` of one rollout of whole episodes, truncated (not terminated) at the
    end: the value of the final observation ``last_value`` ``(n,)`` bootstraps the last step."""
    advantages = np.zeros_like(rewards)
    running = np.zeros(rewards.shape[1])
    for t in range(len(rewards) - 1, -1, -1):
        following = last_value if t == len(rewards) - 1 else values[t + 1]
        delta = rewards[t] + gamma * following - values[t]
        running = delta + gamma * lam * running
        advantages[t] = running
    return advantages


def check_export(policy: RecurrentPolicy, net: PolicyNet, inputs: np.ndarray) -> float:
    """Largest difference between the torch actor and the deployed kernel on the input sequences
    ``inputs`` ``(T, B, inputs)`` (the kernel in float64 from the float32 weights)."""
    with torch.no_grad():
        mean, _ = policy(torch.from_numpy(inputs.astype(np.float32)))
    state = net.start(inputs.shape[1])
    kernel = np.stack([net.step(inputs[t].astype(np.float64), state) for t in range(len(inputs))])
    return float(np.max(np.abs(kernel - mean.numpy())))


@dataclass(frozen=True)
class PPOPlan:
    """What one version's run flies: its ``spec``, the vector environment (``make_env(n, split,
    classes)``), the ``classes`` drawn and scored, the policy's input scaling ``obs_scale`` (the
    observation then the previous action) and the deployed controller (``deployed(net)``)."""

    spec: BenchmarkSpec
    make_env: Callable[..., Any]
    classes: tuple[str, ...]
    obs_scale: tuple[float, ...]
    deployed: Callable[[PolicyNet], Controller]

    @property
    def actions(self) -> int:
        return self.spec.action_dim

    @property
    def inputs(self) -> int:
        return len(self.obs_scale)


def checkpoint_score(
    plan: PPOPlan, net: PolicyNet, n_faults: int, n_seeds: int
) -> tuple[float, float, dict[str, float]]:
    """``(mean settled rate, -median final error deg, settled per class)`` of the deterministic
    policy on the first pinned *train* episodes of every class."""
    cells = [Cell("train", c) for c in plan.classes]
    runs = evaluate_cells(
        lambda _cell: plan.deployed(net), plan.spec, cells, n_faults=n_faults, n_seeds=n_seeds
    )
    rates = {run.cell.label: run.result.settled.rate for run in runs}
    finals = np.concatenate([run.outcomes.final_error_deg for run in runs])
    return float(np.mean(list(rates.values()))), -float(np.median(finals)), rates


def train_recurrent_ppo(request: TrainRequest, budget: PPOBudget, plan: PPOPlan) -> TrainReport:
    """PPO from scratch on the train split of ``plan``'s version; writes the policy and its ``.yaml``."""
    spec, classes, inputs_n, actions_n = plan.spec, plan.classes, plan.inputs, plan.actions
    config = PolicyConfig(lstm_hidden=budget.lstm_hidden, net_arch=budget.net_arch)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    torch.manual_seed(request.seed)
    noise = torch.Generator().manual_seed(request.seed)
    rng = np.random.default_rng(request.seed)
    start = time.monotonic()
    n, steps = budget.n_envs, spec.steps
    scale = torch.tensor(plan.obs_scale, dtype=torch.float32)
    returns: list[float] = []
    history: list[dict] = []
    try:
        env = plan.make_env(n, "train", classes)
        model = ActorCritic(config, budget.log_std_init, inputs_n, actions_n)
        opt = torch.optim.Adam(model.parameters(), lr=budget.learning_rate, eps=1e-5)
        reward_scale = ReturnScale(n, budget.gamma)
        obs, _ = env.reset(seed=int(rng.integers(2**31)))
        best: tuple[tuple[float, float], dict, int] = ((-1.0, -np.inf), {}, 0)

        def checkpoint(done: int, logged: dict) -> tuple[float, float]:
            """Score the actor after ``done`` rollouts, record it in the history (with ``logged``),
            keep it if it is the best so far; returns ``(settled, -median final error)``."""
            nonlocal best
            settled, neg_final, _ = checkpoint_score(
                plan, policy_net(model.actor, config), budget.eval_faults, budget.eval_seeds
            )
            history.append(
                {"rollout": done, "env_steps": done * n * steps, **logged, "train_settled": settled,
                 "median_final_error_deg": round(-neg_final, 3)}
            )  # fmt: skip
            if (settled, neg_final) >= best[0]:
                best = ((settled, neg_final), copy.deepcopy(model.actor.state_dict()), done)
            return settled, neg_final

        if budget.eval_start:
            checkpoint(0, {})
        for it in range(budget.rollouts):
            for group in opt.param_groups:
                group["lr"] = budget.learning_rate * (1.0 - it / budget.rollouts)
            inputs = np.zeros((steps, n, inputs_n), dtype=np.float32)
            actions = np.zeros((steps, n, actions_n), dtype=np.float32)
            logps = np.zeros((steps, n), dtype=np.float32)
            values = np.zeros((steps, n), dtype=np.float32)
            rewards = np.zeros((steps, n))
            raw_return = np.zeros(n)
            prev = np.zeros((n, actions_n), dtype=np.float32)
            a_state = c_state = None
            std = model.log_std.exp().detach()
            with torch.no_grad():
                for t in range(steps):
                    x = torch.from_numpy(np.concatenate((obs, prev), axis=1)) * scale
                    mean, a_state = model.actor(x[None], a_state)
                    value, c_state = model.critic(x[None], c_state)
                    sample = mean[0] + std * torch.randn(mean.shape[1:], generator=noise)
                    logp = torch.distributions.Normal(mean[0], std).log_prob(sample).sum(-1)
                    obs, reward, _, truncated, info = env.step(sample.numpy())
                    inputs[t], actions[t], logps[t], values[t] = x.numpy(), sample.numpy(), logp, value[0]
                    raw_return += reward
                    rewards[t] = reward_scale(reward)
                    prev = np.clip(sample.numpy(), -1.0, 1.0)
                final = torch.from_numpy(np.concatenate((info["final_obs"], prev), axis=1)) * scale
                last_value = model.critic(final[None], c_state)[0][0].numpy()
            if not truncated.all():  # pragma: no cover - the environment's contract
                raise ScftcError("a PPO rollout must be one whole episode per environment")
            reward_scale.episode_end()
            advantages = gae(rewards, values, last_value, budget.gamma, budget.gae_lambda)
            targets = torch.from_numpy((advantages + values).astype(np.float32))
            adv_t = torch.from_numpy(advantages.astype(np.float32))
            x_t, act_t, logp_t = torch.from_numpy(inputs), torch.from_numpy(actions), torch.from_numpy(logps)
            for _ in range(budget.n_epochs):
                order = torch.randperm(n, generator=noise)
                for first in range(0, n, budget.minibatch_envs):
                    pick = order[first : first + budget.minibatch_envs]
                    mean, _ = model.actor(x_t[:, pick])
                    value, _ = model.critic(x_t[:, pick])
                    dist = torch.distributions.Normal(mean, model.log_std.exp())
                    logp = dist.log_prob(act_t[:, pick]).sum(-1)
                    adv = adv_t[:, pick]
                    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
                    ratio = torch.exp(logp - logp_t[:, pick])
                    clipped = ratio.clamp(1.0 - budget.clip_range, 1.0 + budget.clip_range)
                    policy_loss = -torch.min(ratio * adv, clipped * adv).mean()
                    value_loss = (value - targets[:, pick]).pow(2).mean()
                    entropy = dist.entropy().sum(-1).mean()
                    loss = policy_loss + budget.vf_coef * value_loss - budget.ent_coef * entropy
                    opt.zero_grad()
                    loss.backward()
                    nn.utils.clip_grad_norm_(model.parameters(), budget.max_grad_norm)
                    opt.step()
            returns.append(float(raw_return.mean()))
            message = f"rollout {it + 1}/{budget.rollouts}, episode return {returns[-1]:.1f}"
            if (it + 1) % budget.eval_every == 0 or it + 1 == budget.rollouts:
                settled, neg_final = checkpoint(it + 1, {"return": round(returns[-1], 2)})
                message += f", train settled {settled:.3f}, median final error {-neg_final:.1f} deg"
            request.on_progress((it + 1) / budget.rollouts, message)
        policy = RecurrentPolicy(config, inputs_n, actions_n)
        policy.load_state_dict(best[1])
        net = policy_net(policy.eval(), config)
        mismatch = check_export(policy, net, inputs[:, :8].astype(np.float64))
        if mismatch > 1e-4:
            raise ScftcError(f"exported e2e_ppo policy disagrees with the torch actor by {mismatch:.2e}")
        request.on_progress(1.0, "scoring the kept checkpoint on the pinned train cells")
        final_faults, final_seeds = (
            (spec.n_faults, spec.n_seeds)
            if request.budget == "full"
            else (budget.eval_faults, budget.eval_seeds)
        )
        train_rate, neg_final, per_class = checkpoint_score(plan, net, final_faults, final_seeds)
    finally:
        torch.set_num_threads(threads)
    out = request.artifact_out()
    save_policy(numpy_state(policy), config, out)
    wall_s = time.monotonic() - start
    provenance = request.provenance(
        train_rate,
        f"batched recurrent PPO from scratch, {budget.env_steps(steps)} env steps on {spec.version} "
        f"train classes {list(classes)}; wall {wall_s:.0f} s on CPU (1 thread); train_settled_rate = mean "
        f"settled rate over the pinned train cells of those classes ({final_faults} x {final_seeds} "
        "episodes each)",
    )
    params = {
        "config": config.to_dict(),
        "budget": {**asdict(budget), "net_arch": list(budget.net_arch), "env_steps": budget.env_steps(steps)},
        "kept_rollout": best[2],
        "history": history,
        "rollout_mean_episode_return": [round(r, 3) for r in returns[:: max(1, len(returns) // 50)]],
        "final_rollout_return": round(returns[-1], 3) if returns else None,
        "train_settled_per_class": {k: round(v, 4) for k, v in per_class.items()},
        "train_median_final_error_deg": round(-neg_final, 3),
        "export_max_abs_diff": mismatch,
        "wall_s": round(wall_s, 1),
        "weights_file": Path(out).name,
    }
    save_params(request.controller, params, provenance, Path(out).with_suffix(".yaml"))
    return TrainReport(request.controller, Path(out), train_rate, {"wall_s": wall_s, "history": history})
