"""``e2e_ppo`` on ``scftc-v2``: one recurrent network that must fuse the sensors, identify the fault
and allocate the four wheels at once.

Trained from scratch with PPO on the train split of the gymnasium environment
``scftc/AttitudeFTC-v2`` (``training/v2_ppo.py``: a batched PPO written for the vector
environment, which steps every episode as one call of the fused kernel), then exported to plain
weights that v1's numba kernel ``recurrent.policy_step`` runs, so that evaluating it needs neither
torch nor gymnasium. The actor is v1's: an LSTM over the scaled observation and the previous
action, one tanh layer, a linear action head; deployed deterministically (the Gaussian's mean,
clipped to [-1, 1]).

Weights live in ``scftc_cli/weights/v2/e2e_ppo.npz`` with a sidecar ``e2e_ppo.yaml`` (provenance).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from scftc_cli.baselines import recurrent
from scftc_cli.baselines.params import WEIGHTS_DIR
from scftc_cli.baselines.ppo import PolicyConfig, PolicyNet
from scftc_cli.baselines.v2.law import wheels_of
from scftc_cli.errors import ScftcError
from scftc_cli.protocol import Context, Controller

ACTIONS = 4
# The policy's input: [3 head MRPs, 3 validity flags, 20 x gyro, tachometers / 600 rad/s, previous
# action] (rates of ~0.05 rad/s and wheel speeds of up to ~600 rad/s to order 1).
OBS_SCALE = (1.0,) * 12 + (20.0,) * 3 + (1.0 / 600.0,) * 4 + (1.0,) * ACTIONS

__all__ = ["E2EPPO", "OBS_SCALE", "PolicyConfig", "PolicyNet", "load_policy", "policy_input", "save_policy"]


def policy_input(obs: np.ndarray, prev_action: np.ndarray) -> np.ndarray:
    """``(n, 23)`` network input for ``obs`` ``(n, 19)`` and the previous command ``(n, 4)``."""
    return np.concatenate((obs, prev_action), axis=1) * np.asarray(OBS_SCALE)


def weights_path() -> Path:
    return WEIGHTS_DIR / "v2" / "e2e_ppo.npz"


def save_policy(state: Mapping[str, np.ndarray], config: PolicyConfig, path: Path) -> Path:
    """Write the actor's state dict (numpy, float32) and ``config`` to the ``.npz`` file ``path``."""
    return recurrent.save_weights(path, dict(state), config.to_dict())


def load_policy(path: Path | None = None) -> PolicyNet:
    """The committed e2e policy, ready for the kernel (float64)."""
    path = path or weights_path()
    if not path.exists():
        raise ScftcError(f"no weights at {path}; run `scftc train --benchmark scftc-v2 --controller e2e_ppo`")
    state, doc = recurrent.load_weights(path)
    net = PolicyNet.from_state(state, PolicyConfig.from_dict(doc))
    if net.w_ih.shape[0] != len(OBS_SCALE) or net.w_out.shape[1] != ACTIONS:
        raise ScftcError(f"{path}: not a scftc-v2 policy (input {len(OBS_SCALE)}, {ACTIONS} actions)")
    return net


class E2EPPO(Controller):
    """Runs the exported recurrent policy deterministically over the whole batch."""

    def __init__(self, path: Path | None = None, net: PolicyNet | None = None) -> None:
        self.net = net if net is not None else load_policy(path)

    def reset(self, n: int, context: Context) -> None:
        wheels_of(context)  # a clear error on another benchmark version
        self.state = self.net.start(n)
        self.prev_action = np.zeros((n, ACTIONS))

    def act(self, obs: np.ndarray) -> np.ndarray:
        mean = self.net.step(policy_input(obs, self.prev_action), self.state)
        command = np.clip(mean, -1.0, 1.0)
        self.prev_action = command
        return command
