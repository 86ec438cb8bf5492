"""DAgger training of a per-wheel RMA student (``training/student.py``), shared by the versions
whose students fly reaction wheels (``scftc-v2``, ``scftc-v3``).

Each iteration flies a fresh batch of train-split episodes with the student's own latched
estimate in the loop (mixed, early on, with episodes allocated through the teacher's true
effectiveness), so that the student learns on the states it will itself visit; the recorded
per-wheel feature sequences, cut at the change test's restarts, are aggregated in a replay
buffer, and the student's least-squares fit regresses the true effectiveness in force at every
step on which the network ran (``student_loss``). The network is ``StudentModule`` (autograd); the
rollouts fly its weights with the deployed numba kernel (``StudentNet``), and the kept checkpoint
(the best on pinned *train* cells) is written as ``.npz`` with a ``.yaml`` sidecar. Nothing here
sees the test split.

What differs between versions is a ``DaggerPlan``: the spec, the classes, how fresh episodes are
drawn, the recording controller and the deployed one.
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
from torch.nn import functional

from scftc_cli.baselines.params import save_params
from scftc_cli.baselines.student import StudentLayout, StudentNet, save_student
from scftc_cli.protocol import Controller
from scftc_cli.sim.episodes import Episodes
from scftc_cli.sim.rollout import rollout
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.training import TrainReport, TrainRequest, numpy_state, train_settled_rates
from scftc_cli.training.student import RMABudget, StudentModule

DEAD_SCALE = 0.1  # the relative error of a dead wheel's estimate is taken against this


class Recording:
    """Mixin of a training-only controller that records, every step, its estimator's features
    ``(n m, F)``, restarts and active rows ``(n m,)`` and the true gains ``(n m,)``."""

    def start_recording(self) -> None:
        self.features: list[np.ndarray] = []
        self.restarts: list[np.ndarray] = []
        self.active: list[np.ndarray] = []
        self.targets: list[np.ndarray] = []

    def record(self, estimator: Any, true_gain: np.ndarray) -> None:
        """Append this step's ``estimator`` (a ``WheelEstimator``) rows and the true gains ``(n, m)``."""
        self.features.append(estimator.features.astype(np.float32))
        self.restarts.append(estimator.restarted.copy())
        self.active.append(estimator.active.copy())
        self.targets.append(true_gain.reshape(-1).astype(np.float32))


@dataclass(frozen=True)
class DaggerPlan:
    """What one version's DAgger run flies.

    Attributes:
        spec: the version (its steps and full train cell size).
        wheels: the wheels per episode (the student's sequences per episode).
        classes: the train classes the episodes are drawn from and the checkpoint is scored on.
        sample: ``(rng, n) -> n`` fresh train episodes of ``classes``.
        collector: ``(net, config, teacher_mask (n,) bool) ->`` a ``Recording`` controller that
            flies the student, the true gains on the masked episodes.
        deployed: ``(net, config) ->`` the controller as deployed.
        layout, n_features: the student's input layout.
        trim: cut each minibatch after its last step on which the network ran: the loss counts
            only those steps and the network is causal, so the loss is the same and long episodes
            (v3's 2400 steps) cost what their active steps cost. v2 trains without it (its
            committed weights come from the untrimmed run, to the bit).
    """

    spec: BenchmarkSpec
    wheels: int
    classes: tuple[str, ...]
    sample: Callable[[np.random.Generator, int], Episodes]
    collector: Callable[..., Controller]
    deployed: Callable[..., Controller]
    layout: StudentLayout
    n_features: int
    trim: bool = False


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


def student_net(model: StudentModule, layout: StudentLayout, bias_invariant: bool) -> StudentNet:
    """The deployed (numba) form of ``model``'s current weights."""
    return StudentNet.from_state(numpy_state(model), layout, bias_invariant)


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


def _deploy(plan: DaggerPlan, net: StudentNet, config: Any) -> Callable[[], Controller]:
    return lambda: plan.deployed(net, config)


def train_dagger(request: TrainRequest, budget: RMABudget, config: Any, plan: DaggerPlan) -> TrainReport:
    """DAgger-train the student of ``request.controller`` with the deployment settings ``config``
    (a ``StudentConfig``) over ``plan``; writes the weights and their ``.yaml``."""
    spec, classes, layout = plan.spec, plan.classes, plan.layout
    invariant = config.bias_invariant
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    torch.manual_seed(request.seed)
    rng = np.random.default_rng(request.seed)
    start = time.monotonic()
    try:
        model = StudentModule(layout, config.hidden, invariant)
        opt = torch.optim.Adam(model.parameters(), lr=budget.lr)
        total_steps = budget.iterations * budget.grad_steps
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, total_steps, eta_min=budget.lr / 20)
        steps, m = spec.steps, plan.wheels
        # a ring buffer of segments (about 1.5 per wheel sequence: restarts are few)
        capacity = 2 * budget.buffer_iterations * budget.episodes * m
        xs = torch.zeros((capacity, steps, plan.n_features))
        actives = torch.zeros((capacity, steps), dtype=torch.bool)
        targets = torch.zeros((capacity, steps))
        filled, cursor, loss_avg = 0, 0, float("nan")
        best = (-1.0, copy.deepcopy(model.state_dict()))
        history = []
        for it in range(budget.iterations):
            p_teacher = max(0.0, 1.0 - it / max(1.0, budget.teacher_fraction * budget.iterations))
            episodes = plan.sample(rng, budget.episodes)
            mask = rng.random(budget.episodes) < p_teacher
            collector = plan.collector(student_net(model, layout, invariant), config, mask)
            rollout(collector, episodes)
            assert isinstance(collector, Recording)
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
                x_b, active_b, target_b = xs[pick], actives[pick], targets[pick]
                if plan.trim:
                    used = active_b.any(dim=0).nonzero()
                    length = int(used[-1, 0]) + 1 if len(used) else 1
                    x_b, active_b, target_b = x_b[:, :length], active_b[:, :length], target_b[:, :length]
                loss = student_loss(model, x_b, active_b, target_b)
                opt.zero_grad()
                loss.backward()
                torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
                opt.step()
                sched.step()
                loss_avg = loss.item() if np.isnan(loss_avg) else 0.9 * loss_avg + 0.1 * loss.item()
            message = f"iter {it + 1}/{budget.iterations} loss {loss_avg:.4f}"
            if (it + 1) % budget.eval_every == 0 or it + 1 == budget.iterations:
                rates = train_settled_rates(
                    _deploy(plan, student_net(model, layout, invariant), config),
                    classes,
                    budget.eval_faults,
                    budget.eval_seeds,
                    spec=spec,
                )
                rate = float(np.mean(list(rates.values())))
                history.append({"iteration": it + 1, "loss": round(loss_avg, 5), "train_settled": rate})
                if rate >= best[0]:
                    best = (rate, copy.deepcopy(model.state_dict()))
                message += f" train settled {rate:.3f}"
            request.on_progress((it + 1) / budget.iterations, message)
        model.load_state_dict(best[1])
        request.on_progress(1.0, "scoring the kept checkpoint on the pinned train cells")
        full = request.budget == "full"
        final_faults, final_seeds = (
            (spec.n_faults, spec.n_seeds) if full else (budget.eval_faults, budget.eval_seeds)
        )
        per_class = train_settled_rates(
            _deploy(plan, student_net(model, layout, invariant), config),
            classes,
            final_faults,
            final_seeds,
            spec=spec,
        )
        train_rate = float(np.mean(list(per_class.values())))
    finally:
        torch.set_num_threads(threads)
    out = request.artifact_out()
    save_student(numpy_state(model), config, out)
    wall_s = time.monotonic() - start
    provenance = request.provenance(
        train_rate,
        f"DAgger on {spec.version} train classes {list(classes)}; wall {wall_s:.0f} s on CPU (1 thread); "
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
    save_params(request.controller, params, provenance, Path(out).with_suffix(".yaml"))
    return TrainReport(request.controller, Path(out), train_rate, {"wall_s": wall_s, "history": history})
