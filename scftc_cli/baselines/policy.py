"""``e2e_ppo``'s deployed form on every version: one recurrent network that must identify the
fault and control at once, run by a numba kernel (``recurrent.policy_step``).

The policy is sb3-contrib's ``MlpLstmPolicy`` actor (each version's trainer exports its actor to
the same layout): an LSTM over the scaled observation and previous action, tanh layers, a linear
action head; deployed deterministically (the Gaussian's mean, clipped to [-1, 1]). Evaluating it
needs neither torch nor sb3. Each version's ``controllers/ppo.py`` says how its observation is
scaled; its weights live in the version's ``weights/e2e_ppo.npz`` with a sidecar ``e2e_ppo.yaml``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scftc_cli.baselines import recurrent
from scftc_cli.baselines.params import committed_weights
from scftc_cli.errors import ScftcError, UsageError
from scftc_cli.protocol import Context, Controller
from scftc_cli.sim.rows import HEAVY_PARALLEL_MIN_BATCH, run_rows


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
    """The weights of the exported actor (``RecurrentPolicy`` in ``training/policy.py``), laid out
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
        """Mean actions ``(B, actions)`` (unclipped) for the scaled inputs ``x`` ``(B, inputs)``;
        advances ``state`` in place."""
        h, c = state
        action = np.empty((x.shape[0], self.w_out.shape[1]))
        run_rows(
            recurrent.policy_step,
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
            parallel=x.shape[0] >= HEAVY_PARALLEL_MIN_BATCH,
        )
        return action


def save_policy(state: Mapping[str, np.ndarray], config: PolicyConfig, path: Path) -> Path:
    """Write a ``RecurrentPolicy`` state dict (numpy, stored as float32) and ``config`` to the
    ``.npz`` file ``path``."""
    return recurrent.save_weights(path, dict(state), config.to_dict())


def load_policy(path: Path) -> PolicyNet:
    """An exported policy, ready for the kernel (float64)."""
    state, doc = recurrent.load_weights(path)
    return PolicyNet.from_state(state, PolicyConfig.from_dict(doc))


class E2EPPO(Controller):
    """Runs an exported recurrent policy deterministically over the whole batch: the input is the
    observation and the previous command, scaled by ``obs_scale``; the command is the policy's
    mean, clipped to [-1, 1]. A version's ``e2e_ppo`` sets ``obs_scale`` and ``benchmark`` (whose
    committed weights it loads)."""

    obs_scale: tuple[float, ...]
    benchmark: str
    name = "e2e_ppo"

    def __init__(self, path: Path | None = None, net: PolicyNet | None = None) -> None:
        if net is None:
            path = path or committed_weights(self.name, self.benchmark)
            net = load_policy(path)
            if net.w_ih.shape[0] != len(self.obs_scale):
                raise ScftcError(f"{path}: not a policy of {self.benchmark} (input {len(self.obs_scale)})")
        self.net = net

    def policy_input(self, obs: np.ndarray, prev_action: np.ndarray) -> np.ndarray:
        """``(n, obs_dim + action_dim)`` network input for ``obs`` and the previous command."""
        return np.concatenate((obs, prev_action), axis=1) * np.asarray(self.obs_scale)

    def reset(self, n: int, context: Context) -> None:
        if context.benchmark_version != self.benchmark:
            raise UsageError(f"this policy flies {self.benchmark}, not {context.benchmark_version}")
        self.state = self.net.start(n)
        self.prev_action = np.zeros((n, self.net.w_out.shape[1]))

    def act(self, obs: np.ndarray) -> np.ndarray:
        mean = self.net.step(self.policy_input(obs, self.prev_action), self.state)
        command = np.clip(mean, -1.0, 1.0)
        self.prev_action = command
        return command
