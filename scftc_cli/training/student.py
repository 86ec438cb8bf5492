"""The RMA student network as a torch module, shared by every version's trainer: what the deployed
``StudentNet`` (``baselines/student.py``) is saved from, the same network in the same layout.

Features ``(B, T, n_features)`` -> estimate ``(B, T)``, ``B`` the number of per-actuator sequences
(an episode's axes on v1, its wheels on v2). The output is the least-squares fit whose sample
weights and prior the GRU chooses (``baselines/student.py``); the GRU decides which samples to
trust and what to say before the data are informative, the data decide the size of the answer.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional

from scftc_cli.baselines.student import StudentLayout


@dataclass(frozen=True)
class RMABudget:
    """How much work one training run does."""

    iterations: int
    episodes: int  # fresh episodes flown per iteration
    grad_steps: int  # gradient steps per iteration
    minibatch: int  # per-actuator sequences per gradient step
    buffer_iterations: int  # DAgger aggregation: keep this many iterations' data
    teacher_fraction: float  # teacher mixing decays from 1 to 0 over this fraction of the run
    lr: float
    eval_every: int
    eval_faults: int  # pinned train cells used to pick the checkpoint (x eval_seeds)
    eval_seeds: int
    hidden: int = 32


TorchState = tuple[torch.Tensor | None, torch.Tensor | float, torch.Tensor | float]
"""A sequence's GRU state and the fit's two running sums, to continue it."""


class StudentModule(nn.Module):
    """The student of ``layout`` (the module docstring); ``bias_invariant`` reads first
    differences only and none of the features an offset shifts."""

    scale: torch.Tensor  # a registered buffer

    def __init__(self, layout: StudentLayout, hidden: int = 32, bias_invariant: bool = False) -> None:
        super().__init__()
        self.layout = layout
        self.register_buffer("scale", torch.from_numpy(layout.scale(bias_invariant)))
        self.pair = layout.pair(bias_invariant)
        self.inp = nn.Linear(layout.n_features, hidden)
        self.gru = nn.GRU(hidden, hidden, batch_first=True)
        self.head = nn.Sequential(nn.Linear(hidden, hidden), nn.Tanh(), nn.Linear(hidden, 3))

    def heads(
        self, x: torch.Tensor, state: TorchState | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, TorchState]:
        """``(sign_logit, log_magnitude, estimate, state)``, the first three ``(B, T)``: the
        prior's two heads (the magnitude clamped to the layout's bounds) and the fit; pass
        ``state`` back in to continue the sequences."""
        layout = self.layout
        h0, sxy0, sxx0 = state if state is not None else (None, 0.0, 0.0)
        y, h = self.gru(torch.tanh(self.inp(x * self.scale)), h0)
        out = self.head(y)
        logit, log_mag = out[..., 0], out[..., 1].clamp(layout.log_mag_min, layout.log_mag_max)
        prior = torch.tanh(0.5 * logit) * torch.exp(log_mag)
        col_x, col_y, col_valid = self.pair
        weight = functional.softplus(out[..., 2]) * x[..., col_valid]
        xs, ys = x[..., col_x], x[..., col_y]
        sxy = sxy0 + torch.cumsum(weight * xs * ys, dim=1)
        sxx = sxx0 + torch.cumsum(weight * xs * xs, dim=1)
        estimate = (sxy + layout.prior_weight * prior) / (sxx + layout.prior_weight)
        return logit, log_mag, estimate, (h, sxy[:, -1:], sxx[:, -1:])

    def forward(self, x: torch.Tensor, state: TorchState | None = None) -> tuple[torch.Tensor, TorchState]:
        """``(estimate (B, T), state)``."""
        _, _, estimate, state = self.heads(x, state)
        return estimate, state
