"""``e2e_ppo``: one recurrent network that must identify the fault and control at once.

Trained from scratch with PPO on the train split (``scftc train --controller e2e_ppo``, which
uses sb3-contrib's ``RecurrentPPO``), then exported to the plain torch module below, so that
evaluating it needs torch only. The policy is sb3-contrib's ``MlpLstmPolicy`` actor: an LSTM
over the scaled observation and previous action, one tanh layer, a linear action head; deployed
deterministically (the Gaussian's mean, clipped to [-1, 1]). The source study used a GRU; sb3-contrib
offers only the LSTM, which is at least as expressive.

Weights live in ``scftc_cli/weights/e2e_ppo.pt`` with a sidecar ``e2e_ppo.yaml`` (provenance).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from scftc_cli.baselines.params import WEIGHTS_DIR
from scftc_cli.baselines.torch_runtime import inference_mode_threads
from scftc_cli.errors import ScftcError
from scftc_cli.protocol import Context, Controller

# The policy's input: [sigma, 10 w, previous action] (rates of ~0.1 rad/s to order 1).
OBS_SCALE = (1.0, 1.0, 1.0, 10.0, 10.0, 10.0, 1.0, 1.0, 1.0)


@dataclass(frozen=True)
class PolicyConfig:
    """Shape of the exported actor."""

    lstm_hidden: int = 64
    net_arch: tuple[int, ...] = (64,)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PolicyConfig:
        return cls(lstm_hidden=int(d["lstm_hidden"]), net_arch=tuple(int(x) for x in d["net_arch"]))


class RecurrentPolicy(nn.Module):
    """The actor of sb3-contrib's ``MlpLstmPolicy``: ``(T, B, 9)`` scaled inputs -> mean actions
    ``(T, B, 3)`` (unclipped) and the new LSTM state."""

    def __init__(self, config: PolicyConfig) -> None:
        super().__init__()
        self.lstm = nn.LSTM(len(OBS_SCALE), config.lstm_hidden)
        layers: list[nn.Module] = []
        width = config.lstm_hidden
        for units in config.net_arch:
            layers += [nn.Linear(width, units), nn.Tanh()]
            width = units
        self.mlp = nn.Sequential(*layers)
        self.action = nn.Linear(width, 3)

    def forward(
        self, x: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor] | None = None
    ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        y, state = self.lstm(x, state)
        return self.action(self.mlp(y)), state


def policy_input(obs: np.ndarray, prev_action: np.ndarray) -> np.ndarray:
    """``(n, 9)`` network input for ``obs`` ``(n, 6)`` and the previous command ``(n, 3)``."""
    return np.concatenate((obs, prev_action), axis=1) * np.asarray(OBS_SCALE)


def weights_path() -> Path:
    return WEIGHTS_DIR / "e2e_ppo.pt"


def save_policy(policy: RecurrentPolicy, config: PolicyConfig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().float().clone() for k, v in policy.state_dict().items()}
    torch.save({"config": config.to_dict(), "state_dict": state}, path)
    return path


def load_policy(path: Path | None = None) -> RecurrentPolicy:
    """The committed e2e policy, in float64 for reproducible inference."""
    path = path or weights_path()
    if not path.exists():
        raise ScftcError(f"no weights at {path}; run `scftc train --controller e2e_ppo`")
    inference_mode_threads()
    blob = torch.load(path, map_location="cpu", weights_only=True)
    policy = RecurrentPolicy(PolicyConfig.from_dict(blob["config"]))
    policy.load_state_dict(blob["state_dict"])
    return policy.double().eval()


class E2EPPO(Controller):
    """Runs the exported recurrent policy deterministically over the whole batch."""

    def __init__(self, path: Path | None = None, policy: RecurrentPolicy | None = None) -> None:
        self.policy = policy if policy is not None else load_policy(path)

    def reset(self, n: int, context: Context) -> None:
        self.state: tuple[torch.Tensor, torch.Tensor] | None = None
        self.prev_action = np.zeros((n, 3))

    @torch.no_grad()
    def act(self, obs: np.ndarray) -> np.ndarray:
        x = torch.from_numpy(policy_input(obs, self.prev_action)).to(torch.float64)[None]
        mean, self.state = self.policy(x, self.state)
        command = np.clip(mean[0].numpy(), -1.0, 1.0)
        self.prev_action = command
        return command
