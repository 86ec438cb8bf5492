"""DAgger training of a per-wheel RMA student (``training/student.py``), shared by the versions
whose students fly reaction wheels (each version folder's ``training/rma.py`` gives its plan).

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
from collections import deque
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
        prefixes: keep only each segment's active prefix (``active_prefixes``, ``PrefixBuffer``):
            the same loss, a fraction of the memory and time on long episodes (v3's 2400
            steps). v2 trains on whole segments in a ring buffer (its committed weights come from
            that run, to the bit).
    """

    spec: BenchmarkSpec
    wheels: int
    classes: tuple[str, ...]
    sample: Callable[[np.random.Generator, int], Episodes]
    collector: Callable[..., Controller]
    deployed: Callable[..., Controller]
    layout: StudentLayout
    n_features: int
    prefixes: bool = False


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


def loss_terms(
    model: StudentModule, x: torch.Tensor, active: torch.Tensor, gain: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The four sums ``student_loss`` is made of, over segments ``x`` ``(B, T, F)`` with ``active``
    and ``gain`` ``(B, T)``: the weighted fit and magnitude terms, the active steps, the sign term
    over working wheels, and those steps. Sums over parts of a minibatch add up to the whole's."""
    logit, log_mag, g_hat, _ = model.heads(x)
    weight = active.to(x.dtype)
    scale = gain.abs().clamp_min(DEAD_SCALE)
    fit = functional.smooth_l1_loss((g_hat - gain) / scale, torch.zeros_like(gain), reduction="none")
    working = weight * (gain != 0).to(x.dtype)
    sign = functional.binary_cross_entropy_with_logits(logit, (gain > 0).to(x.dtype), reduction="none")
    magnitude = functional.smooth_l1_loss(log_mag, scale.log(), reduction="none")
    return ((fit + magnitude) * weight).sum(), weight.sum(), (sign * working).sum(), working.sum()


def combined_loss(
    fit: torch.Tensor, total: torch.Tensor, sign: torch.Tensor, working: torch.Tensor
) -> torch.Tensor:
    """``student_loss`` from its sums (``loss_terms``)."""
    return fit / total.clamp_min(1.0) + sign / working.clamp_min(1.0)


def student_loss(
    model: StudentModule, x: torch.Tensor, active: torch.Tensor, gain: torch.Tensor
) -> torch.Tensor:
    """Over the steps ``active`` ``(B, T)`` where the network ran (inside the segment, not latched)
    of segments ``x`` whose true effectiveness is ``gain`` ``(B, T)``: Huber on the fit's relative
    error (the allocation divides by it; a dead wheel's error is taken against ``DEAD_SCALE``),
    plus cross-entropy on the prior's sign (working wheels) and Huber on its ``log |g|``."""
    return combined_loss(*loss_terms(model, x, active, gain))


class WholeBuffer:
    """DAgger's aggregation as v2 trains: a ring buffer of ``capacity`` whole segments
    (``split_segments``, zero-padded to ``steps``), minibatches drawn uniformly over the filled
    rows (torch's generator)."""

    def __init__(self, capacity: int, steps: int, n_features: int) -> None:
        self.capacity = capacity
        self.xs = torch.zeros((capacity, steps, n_features))
        self.actives = torch.zeros((capacity, steps), dtype=torch.bool)
        self.targets = torch.zeros((capacity, steps))
        self.filled, self.cursor = 0, 0

    def add(self, restart: np.ndarray, x: np.ndarray, active: np.ndarray, target: np.ndarray) -> None:
        """Keep one iteration's sequences (``(B, T, ...)``), overwriting the oldest."""
        inside, x, active, target = split_segments(restart, x, active, target)
        rows = len(inside)
        idx = (self.cursor + torch.arange(rows)) % self.capacity
        self.xs[idx] = torch.from_numpy(x)
        self.actives[idx] = torch.from_numpy(active & inside)
        self.targets[idx] = torch.from_numpy(target)
        self.cursor = (self.cursor + rows) % self.capacity
        self.filled = min(self.capacity, self.filled + rows)

    def loss(self, model: StudentModule, size: int) -> torch.Tensor:
        """``student_loss`` of ``size`` segments drawn with replacement."""
        pick = torch.randint(self.filled, (size,))
        return student_loss(model, self.xs[pick], self.actives[pick], self.targets[pick])


@dataclass(frozen=True)
class Prefixes:
    """The active prefixes of one iteration's segments, packed end to end: ``x`` ``(N, F)``,
    ``active`` and ``target`` ``(N,)``, segment ``s`` at ``[start[s], start[s] + length[s])``.

    A latch only re-opens at a restart, and a restart starts a segment, so the steps on which the
    network ran are a prefix of each segment; the rest of a segment never enters the loss (weight
    0, and the network is causal). Long episodes hold mostly latched steps: on v3's train split
    about 8 % of the steps are active and three in four prefixes end within 50 steps."""

    x: torch.Tensor
    active: torch.Tensor
    target: torch.Tensor
    start: np.ndarray
    length: np.ndarray


def active_prefixes(restart: np.ndarray, x: np.ndarray, active: np.ndarray, target: np.ndarray) -> Prefixes:
    """``Prefixes`` of the sequences ``x`` ``(B, T, F)``, ``active`` and ``target`` ``(B, T)``
    cut at ``restart`` ``(B, T)``: each segment up to its last active step (empty ones left out)."""
    count, steps = restart.shape
    cuts = restart.copy()
    cuts[:, 0] = True
    row, start = np.nonzero(cuts)
    base = row * steps + start  # each segment's first step, flat
    segment = np.cumsum(cuts.reshape(-1)) - 1  # the segment of every flat step
    flat = np.flatnonzero(active.reshape(-1))
    last = np.full(len(base), -1, dtype=np.int64)
    np.maximum.at(last, segment[flat], flat - base[segment[flat]])
    keep = last >= 0
    base, length = base[keep], last[keep] + 1
    offset = np.concatenate([[0], np.cumsum(length)[:-1]]).astype(np.int64)
    source = np.repeat(base - offset, length) + np.arange(int(length.sum()))
    return Prefixes(
        x=torch.from_numpy(x.reshape(count * steps, -1)[source]),
        active=torch.from_numpy(active.reshape(-1)[source]),
        target=torch.from_numpy(target.reshape(-1)[source]),
        start=offset,
        length=length,
    )


class PrefixBuffer:
    """DAgger's aggregation over the last ``iterations`` iterations' ``Prefixes``: minibatches
    are drawn uniformly over their segments (torch's generator), sorted by length and flown in
    buckets of ``bucket`` segments, each padded to its own longest: the same loss as the padded
    minibatch (``loss_terms`` add up), at a fraction of the cost when a few prefixes are long."""

    def __init__(self, iterations: int, bucket: int = 32) -> None:
        self.parts: deque[Prefixes] = deque(maxlen=iterations)
        self.bucket = bucket

    def add(self, restart: np.ndarray, x: np.ndarray, active: np.ndarray, target: np.ndarray) -> None:
        """Keep one iteration's sequences (``(B, T, ...)``, ``active_prefixes``)."""
        self.parts.append(active_prefixes(restart, x, active, target))

    def loss(self, model: StudentModule, size: int) -> torch.Tensor:
        """``student_loss`` of ``size`` segments drawn with replacement."""
        counts = np.array([len(p.length) for p in self.parts])
        pick = torch.randint(int(counts.sum()), (size,)).numpy()
        part = np.searchsorted(np.cumsum(counts), pick, side="right")
        index = pick - (np.cumsum(counts) - counts)[part]
        length = np.array([self.parts[p].length[i] for p, i in zip(part, index, strict=True)])
        order = np.argsort(length, kind="stable")
        sums: list[torch.Tensor] = []
        for chunk in np.array_split(order, max(1, -(-size // self.bucket))):
            longest = int(length[chunk].max())
            rows = [self._padded(self.parts[part[j]], index[j], longest) for j in chunk]
            x, active, target = (torch.stack(column) for column in zip(*rows, strict=True))
            terms = loss_terms(model, x, active, target)
            sums = list(terms) if not sums else [a + b for a, b in zip(sums, terms, strict=True)]
        return combined_loss(*sums)

    @staticmethod
    def _padded(p: Prefixes, s: int, longest: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Segment ``s`` of ``p`` padded to ``longest`` steps (zeros, inactive, gain 1)."""
        start, n = int(p.start[s]), int(p.length[s])
        x = p.x.new_zeros((longest, p.x.shape[1]))
        x[:n] = p.x[start : start + n]
        active = torch.zeros(longest, dtype=torch.bool)
        active[:n] = p.active[start : start + n]
        target = p.target.new_ones(longest)
        target[:n] = p.target[start : start + n]
        return x, active, target


def _deploy(plan: DaggerPlan, net: StudentNet, config: Any) -> Callable[[], Controller]:
    return lambda: plan.deployed(net, config)


def train_dagger(request: TrainRequest, budget: RMABudget, config: Any, plan: DaggerPlan) -> TrainReport:
    """DAgger-train the student of ``request.controller`` with the deployment settings ``config``
    (a ``StudentConfig``) over ``plan``; writes the weights and their ``.yaml``."""
    spec, classes, layout, n_features = plan.spec, plan.classes, plan.layout, plan.n_features
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
        capacity = 2 * budget.buffer_iterations * budget.episodes * plan.wheels  # ~1.5 segments per wheel
        buffer: WholeBuffer | PrefixBuffer = (
            PrefixBuffer(budget.buffer_iterations)
            if plan.prefixes
            else WholeBuffer(capacity, spec.steps, n_features)
        )
        loss_avg = float("nan")
        best = (-1.0, copy.deepcopy(model.state_dict()))
        history = []
        for it in range(budget.iterations):
            p_teacher = max(0.0, 1.0 - it / max(1.0, budget.teacher_fraction * budget.iterations))
            episodes = plan.sample(rng, budget.episodes)
            mask = rng.random(budget.episodes) < p_teacher
            collector = plan.collector(student_net(model, layout, invariant), config, mask)
            rollout(collector, episodes)
            assert isinstance(collector, Recording)
            buffer.add(
                np.stack(collector.restarts, axis=1),
                np.stack(collector.features, axis=1),
                np.stack(collector.active, axis=1),
                np.stack(collector.targets, axis=1),
            )
            model.train()
            for _ in range(budget.grad_steps):
                loss = buffer.loss(model, budget.minibatch)
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
