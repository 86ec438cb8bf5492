"""Trainers of ``rma_student`` and ``rma_dob`` on ``scftc-v2``: DAgger on the train split.

As on v1 (``versions/v1/training/rma.py``): each iteration flies a fresh batch of train-split episodes
(``sample_episodes_batch``) with the student's own latched estimate in the loop (mixed, early on,
with episodes allocated through the teacher's true ``g(t)``), so that the student learns on the
states it will itself visit; the recorded per-wheel feature sequences, with the change test's
restarts, are aggregated in a replay buffer, and the student's least-squares fit regresses the
true effectiveness in force at every step on which the network ran (``student_loss``).
``rma_dob``'s student flies with its offset and friction observer in the loop and reads only
bias-invariant features.

The network is the shared torch module ``StudentModule`` (``training/student.py``, autograd); the
rollouts fly its weights with the deployed numba kernel (``StudentNet``), and the kept checkpoint
is written as ``.npz``. Nothing here sees the test split; the checkpoint kept is the best on
pinned *train* cells.
"""

from __future__ import annotations

import copy
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from torch.nn import functional

from scftc_cli.baselines.params import save_params
from scftc_cli.baselines.student import StudentNet, save_student
from scftc_cli.protocol import Context
from scftc_cli.sim.rollout import rollout
from scftc_cli.training import TrainReport, TrainRequest, numpy_state, train_settled_rates
from scftc_cli.training.student import RMABudget, StudentModule
from scftc_cli.versions.v2.controllers.rma import StudentController
from scftc_cli.versions.v2.controllers.student import LAYOUT, N_FEATURES, StudentConfig
from scftc_cli.versions.v2.sim.faults import sample_episodes_batch
from scftc_cli.versions.v2.sim.testbed import public_context
from scftc_cli.versions.v2.spec import V2

CLASSES = {
    "rma_student": ("sign", "gain", "loss"),
    "rma_dob": ("sign", "gain", "gain_bias", "friction", "loss"),
}
DEAD_SCALE = 0.1  # the relative error of a dead wheel's estimate is taken against this


def split_segments(restart: np.ndarray, *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """Cut every sequence at its restarts: ``restart`` ``(B, T)`` (before the step) and ``arrays``
    ``(B, T, ...)`` -> ``(inside (S, T), *segments (S, T, ...))``, each segment moved to start at
    step 0 and zero-padded; ``inside`` marks its real steps. Segment ``j`` of a sequence runs from
    its ``j``-th start (0 or a restart) to the next."""
    count, steps = restart.shape
    cuts = restart.copy()
    cuts[:, 0] = True
    row, start = np.nonzero(cuts)
    stop = np.append(start[1:], steps)
    stop = np.where(np.append(row[1:], -1) == row, stop, steps)
    length = stop - start
    inside = np.arange(steps)[None, :] < length[:, None]
    source = np.minimum(start[:, None] + np.arange(steps)[None, :], steps - 1)
    out = []
    for a in arrays:
        seg = a[row[:, None], source]
        pad = inside.reshape(inside.shape + (1,) * (a.ndim - 2))
        out.append(np.where(pad, seg, np.zeros((), dtype=a.dtype)))
    return (inside, *out)


def student_net(model: StudentModule, config: StudentConfig) -> StudentNet:
    """The deployed (numba) form of ``model``'s current weights."""
    return StudentNet.from_state(numpy_state(model), LAYOUT, config.bias_invariant)


BUDGETS: dict[str, RMABudget] = {
    "quick": RMABudget(
        iterations=6,
        episodes=32,
        grad_steps=4,
        minibatch=64,
        buffer_iterations=3,
        teacher_fraction=0.5,
        lr=3e-3,
        eval_every=3,
        eval_faults=3,
        eval_seeds=2,
    ),
    "full": RMABudget(
        iterations=120,
        episodes=192,
        grad_steps=12,
        minibatch=256,
        buffer_iterations=8,
        teacher_fraction=0.25,
        lr=3e-3,
        eval_every=15,
        eval_faults=20,
        eval_seeds=5,
    ),
}


class _DaggerController(StudentController):
    """Training-only (privileged) controller: the student in the loop, except on the episodes of
    ``teacher_mask`` where the true ``g(t)`` is allocated through; records every step's features,
    restarts, the rows the network ran on and the true gains."""

    privileged = True

    def __init__(self, net: StudentNet, config: StudentConfig, teacher_mask: np.ndarray) -> None:
        super().__init__(net=net, config=config)
        self.teacher_mask = teacher_mask[:, None]

    def reset(self, n: int, context: Context) -> None:
        if context.fault is None:
            raise ValueError("the DAgger collector needs the true fault")
        self.fault = context.fault
        super().reset(n, public_context(n))  # the student itself never sees the fault
        self.k = 0
        self.features: list[np.ndarray] = []
        self.restarts: list[np.ndarray] = []
        self.active: list[np.ndarray] = []
        self.targets: list[np.ndarray] = []

    def gain_hat(self, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        true_gain = self.fault.at(self.k)[0]
        gain = self.estimator.observe(gyro, tach, (self.teacher_mask, true_gain))
        est = self.estimator
        self.k += 1
        self.features.append(est.features.astype(np.float32))
        self.restarts.append(est.restarted.copy())
        self.active.append(est.active.copy())
        self.targets.append(true_gain.reshape(-1).astype(np.float32))
        return gain


def settled_rate(
    model: StudentModule, config: StudentConfig, classes: tuple[str, ...], n_faults: int, n_seeds: int
) -> float:
    """Mean settled rate over the pinned *train* cells of ``classes``."""
    net = student_net(model, config)
    rates = train_settled_rates(
        lambda: StudentController(net=net, config=config), classes, n_faults, n_seeds, spec=V2
    )
    return float(np.mean(list(rates.values())))


def student_loss(
    model: StudentModule, x: torch.Tensor, active: torch.Tensor, gain: torch.Tensor
) -> torch.Tensor:
    """Over the steps ``active`` ``(B, T)`` where the network ran (inside the segment, not latched)
    of segments ``x`` whose true effectiveness is ``gain`` ``(B, T)``: Huber on the fit's relative
    error (the allocation divides by it; a dead wheel's error is taken against ``DEAD_SCALE``),
    plus cross-entropy on the prior's sign (working wheels) and Huber on its ``log |g|``."""
    logit, log_mag, g_hat, _ = model.heads(x)
    weight = active.to(x.dtype)
    total = weight.sum().clamp_min(1.0)
    scale = gain.abs().clamp_min(DEAD_SCALE)
    fit = functional.smooth_l1_loss((g_hat - gain) / scale, torch.zeros_like(gain), reduction="none")
    working = weight * (gain != 0).to(x.dtype)
    sign = functional.binary_cross_entropy_with_logits(logit, (gain > 0).to(x.dtype), reduction="none")
    magnitude = functional.smooth_l1_loss(log_mag, scale.log(), reduction="none")
    return ((fit + magnitude) * weight).sum() / total + (sign * working).sum() / working.sum().clamp_min(1.0)


def student_config(name: str, budget: RMABudget) -> StudentConfig:
    """The deployment settings of ``name``: ``rma_dob`` is bias-invariant with the observer."""
    dob = name == "rma_dob"
    return StudentConfig(hidden=budget.hidden, bias_invariant=dob, observer=dob)


def train_student(request: TrainRequest) -> TrainReport:
    """DAgger-train the student of ``request.controller`` (``rma_student`` or ``rma_dob``)."""
    name, budget = request.controller, BUDGETS[request.budget]
    classes = CLASSES[name]
    config = student_config(name, budget)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    torch.manual_seed(request.seed)
    rng = np.random.default_rng(request.seed)
    start = time.monotonic()
    try:
        model = StudentModule(LAYOUT, config.hidden, config.bias_invariant)
        opt = torch.optim.Adam(model.parameters(), lr=budget.lr)
        total_steps = budget.iterations * budget.grad_steps
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, total_steps, eta_min=budget.lr / 20)
        steps, m = V2.steps, V2.action_dim
        # a ring buffer of segments (about 1.5 per wheel sequence: restarts are few)
        capacity = 2 * budget.buffer_iterations * budget.episodes * m
        xs = torch.zeros((capacity, steps, N_FEATURES))
        actives = torch.zeros((capacity, steps), dtype=torch.bool)
        targets = torch.zeros((capacity, steps))
        filled, cursor, loss_avg = 0, 0, float("nan")
        best = (-1.0, copy.deepcopy(model.state_dict()))
        history = []
        for it in range(budget.iterations):
            p_teacher = max(0.0, 1.0 - it / max(1.0, budget.teacher_fraction * budget.iterations))
            episodes = sample_episodes_batch(rng, budget.episodes, "train", classes)
            mask = rng.random(budget.episodes) < p_teacher
            collector = _DaggerController(student_net(model, config), config, mask)
            rollout(collector, episodes)
            inside, x, active, target = split_segments(
                np.stack(collector.restarts, axis=1),
                np.stack(collector.features, axis=1),
                np.stack(collector.active, axis=1),
                np.stack(collector.targets, axis=1),
            )
            rows = len(inside)
            idx = (cursor + torch.arange(rows)) % capacity
            xs[idx] = torch.from_numpy(x)
            actives[idx] = torch.from_numpy(active & inside)
            targets[idx] = torch.from_numpy(target)
            cursor, filled = (cursor + rows) % capacity, min(capacity, filled + rows)
            model.train()
            for _ in range(budget.grad_steps):
                pick = torch.randint(filled, (budget.minibatch,))
                loss = student_loss(model, xs[pick], actives[pick], targets[pick])
                opt.zero_grad()
                loss.backward()
                torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
                opt.step()
                sched.step()
                loss_avg = loss.item() if np.isnan(loss_avg) else 0.9 * loss_avg + 0.1 * loss.item()
            message = f"iter {it + 1}/{budget.iterations} loss {loss_avg:.4f}"
            if (it + 1) % budget.eval_every == 0 or it + 1 == budget.iterations:
                rate = settled_rate(model, config, classes, budget.eval_faults, budget.eval_seeds)
                history.append({"iteration": it + 1, "loss": round(loss_avg, 5), "train_settled": rate})
                if rate >= best[0]:
                    best = (rate, copy.deepcopy(model.state_dict()))
                message += f" train settled {rate:.3f}"
            request.on_progress((it + 1) / budget.iterations, message)
        model.load_state_dict(best[1])
        request.on_progress(1.0, "scoring the kept checkpoint on the pinned train cells")
        final_faults, final_seeds = (
            (V2.n_faults, V2.n_seeds) if request.budget == "full" else (budget.eval_faults, budget.eval_seeds)
        )
        net = student_net(model, config)
        per_class = train_settled_rates(
            lambda: StudentController(net=net, config=config), classes, final_faults, final_seeds, spec=V2
        )
        train_rate = float(np.mean(list(per_class.values())))
    finally:
        torch.set_num_threads(threads)
    out = request.artifact_out()
    save_student(numpy_state(model), config, out)
    wall_s = time.monotonic() - start
    provenance = request.provenance(
        train_rate,
        f"DAgger on scftc-v2 train classes {list(classes)}; wall {wall_s:.0f} s on CPU (1 thread); "
        f"train_settled_rate = mean settled rate over the pinned train cells of those classes "
        f"({final_faults} x {final_seeds} episodes each)",
    )
    params = {
        "config": config.to_dict(),
        "budget": asdict(budget),
        "history": history,
        "train_settled_per_class": {k: round(v, 4) for k, v in per_class.items()},
        "wall_s": round(wall_s, 1),
        "weights_file": Path(out).name,
    }
    save_params(name, params, provenance, Path(out).with_suffix(".yaml"))
    return TrainReport(name, Path(out), train_rate, {"wall_s": wall_s, "history": history})
