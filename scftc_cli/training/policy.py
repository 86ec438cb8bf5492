"""The torch form of ``e2e_ppo``'s actor, shared by every version's PPO trainer: what the numba
kernel's ``PolicyNet`` (``baselines/policy.py``) is exported from."""

from __future__ import annotations

import torch
from torch import nn

from scftc_cli.baselines.policy import PolicyConfig, PolicyNet
from scftc_cli.training import numpy_state


class RecurrentPolicy(nn.Module):
    """The actor of sb3-contrib's ``MlpLstmPolicy``: ``(T, B, inputs)`` scaled inputs -> mean
    actions ``(T, B, actions)`` (unclipped) and the new LSTM state (a version's ``obs_dim +
    action_dim`` inputs and ``action_dim`` actions). Evaluation runs its weights with the numba
    kernel (``PolicyNet``)."""

    def __init__(self, config: PolicyConfig, inputs: int, actions: int) -> None:
        super().__init__()
        self.lstm = nn.LSTM(inputs, config.lstm_hidden)
        layers: list[nn.Module] = []
        width = config.lstm_hidden
        for units in config.net_arch:
            layers += [nn.Linear(width, units), nn.Tanh()]
            width = units
        self.mlp = nn.Sequential(*layers)
        self.action = nn.Linear(width, actions)

    def forward(
        self, x: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor] | None = None
    ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        y, state = self.lstm(x, state)
        return self.action(self.mlp(y)), state


def policy_net(policy: RecurrentPolicy, config: PolicyConfig) -> PolicyNet:
    """The deployed (numba) form of ``policy``'s weights (rounded to float32, as saved)."""
    return PolicyNet.from_state(numpy_state(policy), config)
