"""``e2e_ppo``: one recurrent network that must identify the fault and control at once.

Trained from scratch with PPO on the train split (``scftc train --controller e2e_ppo``, which
uses sb3-contrib's ``RecurrentPPO``), then exported to plain weights that a numba kernel runs
(``recurrent.policy_step``), so that evaluating it needs neither torch nor sb3. The policy is
sb3-contrib's ``MlpLstmPolicy`` actor: an LSTM over the scaled observation and previous action,
one tanh layer, a linear action head; deployed deterministically (the Gaussian's mean, clipped to
[-1, 1]). The source study used a GRU; sb3-contrib offers only the LSTM, which is at least as
expressive.

Weights live in ``scftc_cli/weights/e2e_ppo.npz`` with a sidecar ``e2e_ppo.yaml`` (provenance).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scftc_cli.baselines import recurrent
from scftc_cli.baselines.params import WEIGHTS_DIR
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


@dataclass(frozen=True, eq=False)
class PolicyNet:
    """The weights of the exported actor (``RecurrentPolicy`` in ``training/ppo.py``), laid out
    for the kernel: float64 copies of the float32 arrays as trained, matrices transposed to
    ``(in, out)``, one entry of ``w_mlp``/``b_mlp`` per tanh layer."""

    w_ih: np.ndarray
    b_ih: np.ndarray
    w_hh: np.ndarray
    b_hh: np.ndarray
    w_mlp: tuple[np.ndarray, ...]
    b_mlp: tuple[np.ndarray, ...]
    w_out: np.ndarray
    b_out: np.ndarray

    @classmethod
    def from_state(cls, state: Mapping[str, np.ndarray], config: PolicyConfig) -> PolicyNet:
        """From a ``RecurrentPolicy`` state dict as numpy arrays (the keys of the ``.npz`` file)."""
        t, f = recurrent.transposed, recurrent.as_float64
        layers = range(len(config.net_arch))  # the tanh layers sit at mlp.0, mlp.2, ...
        return cls(
            w_ih=t(state["lstm.weight_ih_l0"]),
            b_ih=f(state["lstm.bias_ih_l0"]),
            w_hh=t(state["lstm.weight_hh_l0"]),
            b_hh=f(state["lstm.bias_hh_l0"]),
            w_mlp=tuple(t(state[f"mlp.{2 * i}.weight"]) for i in layers),
            b_mlp=tuple(f(state[f"mlp.{2 * i}.bias"]) for i in layers),
            w_out=t(state["action.weight"]),
            b_out=f(state["action.bias"]),
        )

    @property
    def hidden(self) -> int:
        return self.w_hh.shape[0]

    def start(self, rows: int) -> tuple[np.ndarray, np.ndarray]:
        """The LSTM state ``(h, c)`` of ``rows`` fresh sequences."""
        return np.zeros((rows, self.hidden)), np.zeros((rows, self.hidden))

    def step(self, x: np.ndarray, state: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """Mean actions ``(B, 3)`` (unclipped) for the scaled inputs ``x`` ``(B, 9)``; advances
        ``state`` in place."""
        h, c = state
        action = np.empty((x.shape[0], self.w_out.shape[1]))
        recurrent.policy_step(
            np.ascontiguousarray(x, dtype=np.float64),
            h,
            c,
            action,
            self.w_ih,
            self.b_ih,
            self.w_hh,
            self.b_hh,
            self.w_mlp,
            self.b_mlp,
            self.w_out,
            self.b_out,
        )
        return action


def policy_input(obs: np.ndarray, prev_action: np.ndarray) -> np.ndarray:
    """``(n, 9)`` network input for ``obs`` ``(n, 6)`` and the previous command ``(n, 3)``."""
    return np.concatenate((obs, prev_action), axis=1) * np.asarray(OBS_SCALE)


def weights_path() -> Path:
    return WEIGHTS_DIR / "e2e_ppo.npz"


def save_policy(state: Mapping[str, np.ndarray], config: PolicyConfig, path: Path) -> Path:
    """Write a ``RecurrentPolicy`` state dict (numpy, stored as float32) and ``config`` to the
    ``.npz`` file ``path``."""
    return recurrent.save_weights(path, dict(state), config.to_dict())


def load_policy(path: Path | None = None) -> PolicyNet:
    """The committed e2e policy, ready for the kernel (float64)."""
    path = path or weights_path()
    if not path.exists():
        raise ScftcError(f"no weights at {path}; run `scftc train --controller e2e_ppo`")
    state, doc = recurrent.load_weights(path)
    return PolicyNet.from_state(state, PolicyConfig.from_dict(doc))


class E2EPPO(Controller):
    """Runs the exported recurrent policy deterministically over the whole batch."""

    def __init__(self, path: Path | None = None, net: PolicyNet | None = None) -> None:
        self.net = net if net is not None else load_policy(path)

    def reset(self, n: int, context: Context) -> None:
        self.state = self.net.start(n)
        self.prev_action = np.zeros((n, 3))

    def act(self, obs: np.ndarray) -> np.ndarray:
        mean = self.net.step(policy_input(obs, self.prev_action), self.state)
        command = np.clip(mean, -1.0, 1.0)
        self.prev_action = command
        return command
