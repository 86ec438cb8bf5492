"""Trainers of ``rma_student`` and ``rma_dob``: DAgger on the train split.

Each iteration flies a fresh batch of train-split episodes with the student's own latched
estimate in the loop (mixed, early on, with episodes driven by the teacher's true ``theta``), so
that the student learns on the states it will itself visit; the recorded feature sequences are
aggregated in a replay buffer and the student's least-squares fit regresses the true
``theta = g/f`` at every step (``student_loss``).
``rma_dob``'s gain student flies with train-split biases and the disturbance observer in the
loop, so the estimate it learns is the one the observer composes with, and reads only features
that a constant bias cannot shift (``BIASED_FEATURES`` in ``controllers/rma.py``).

The network is the shared torch module ``StudentModule`` (``training/student.py``, autograd). The
trainer's rollouts (DAgger collection, checkpoint choice, the reported score) fly that module in
float64 (``TorchStudentNet``), exactly as when the committed weights were trained, so `scftc
train` regenerates them bit for bit; evaluation flies the same weights on the numba kernel
(``StudentNet``, equal to ~1e-15, identical gates). The kept checkpoint is written as ``.npz``.
Nothing here sees the test split; the checkpoint kept is the best on pinned *train* cells.
"""

from __future__ import annotations

import copy
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch.nn import functional

from scftc_cli.baselines.params import save_params
from scftc_cli.baselines.student import save_student
from scftc_cli.protocol import Context
from scftc_cli.sim.rollout import rollout
from scftc_cli.training import TrainReport, TrainRequest, numpy_state, train_settled_rates
from scftc_cli.training.student import RMABudget, StudentModule, TorchState
from scftc_cli.versions.v1.controllers.rma import LAYOUT, LatchConfig, StudentConfig, StudentController
from scftc_cli.versions.v1.sim.faults import sample_episodes
from scftc_cli.versions.v1.sim.testbed import public_context
from scftc_cli.versions.v1.spec import V1

OBSERVER_GAIN = 0.1  # lambda ~ 0.1 keeps the observer pole inside the envelope


@dataclass
class TorchStudentState:
    """The torch module's recurrent state and the last ``theta_hat`` ``(B,)``."""

    torch_state: TorchState | None
    theta: np.ndarray


class TorchStudentNet:
    """A frozen float64 copy of ``model``, stepped like ``StudentNet`` (``baselines.rma.ThetaNet``).

    Every row is advanced every step (latched axes too; nothing reads them), as the trainer did
    when the committed weights were made: the numba kernel agrees with this to ~1e-15, but a
    400-step closed loop with a latch can turn that into a different latch step in rare episodes,
    hence different training data, and the weights must regenerate bit for bit.
    """

    def __init__(self, model: StudentModule) -> None:
        self.model = copy.deepcopy(model).double().eval()

    def start(self, rows: int) -> TorchStudentState:
        return TorchStudentState(None, np.zeros(rows))

    @torch.no_grad()
    def step(self, x: np.ndarray, state: TorchStudentState, active: np.ndarray | None = None) -> np.ndarray:
        theta, state.torch_state = self.model(
            torch.from_numpy(x).to(torch.float64)[:, None, :], state.torch_state
        )
        state.theta = theta[:, 0].double().numpy()
        return state.theta


BUDGETS: dict[str, RMABudget] = {
    "quick": RMABudget(
        iterations=12,
        episodes=64,
        grad_steps=6,
        minibatch=96,
        buffer_iterations=4,
        teacher_fraction=0.5,
        lr=3e-3,
        eval_every=4,
        eval_faults=5,
        eval_seeds=2,
    ),
    "full": RMABudget(
        iterations=160,
        episodes=256,
        grad_steps=14,
        minibatch=256,
        buffer_iterations=8,
        teacher_fraction=0.25,
        lr=3e-3,
        eval_every=20,
        eval_faults=20,
        eval_seeds=5,
    ),
}
CLASSES = {"rma_student": ("sign", "gain"), "rma_dob": ("sign", "gain", "gain_bias")}


class _DaggerController(StudentController):
    """Training-only (privileged) controller: the student in the loop, except on the episodes of
    ``teacher_mask`` where the true ``theta`` drives; records every step's student features."""

    privileged = True

    def __init__(self, net: TorchStudentNet, config: StudentConfig, teacher_mask: np.ndarray) -> None:
        super().__init__(net=net, config=config)
        self.teacher_mask = teacher_mask[:, None]
        self.recorded: list[np.ndarray] = []

    def reset(self, n: int, context: Context) -> None:
        if context.fault is None:
            raise ValueError("the DAgger collector needs the true fault")
        self.true_theta = context.fault.theta
        super().reset(n, public_context(n))  # the student itself never sees the fault
        self.recorded = []

    def theta_hat(self, obs: np.ndarray) -> np.ndarray:
        theta_hat = super().theta_hat(obs)
        self.recorded.append(self.estimator.features.astype(np.float32))
        return np.where(self.teacher_mask, self.true_theta, theta_hat)


def settled_rate(
    model: StudentModule, config: StudentConfig, classes: tuple[str, ...], n_faults: int, n_seeds: int
) -> float:
    """Mean settled rate over the pinned *train* cells of ``classes``."""
    net = TorchStudentNet(model)
    rates = train_settled_rates(
        lambda: StudentController(net=net, config=config), classes, n_faults, n_seeds, V1
    )
    return float(np.mean(list(rates.values())))


def student_loss(model: StudentModule, x: torch.Tensor, theta: torch.Tensor) -> torch.Tensor:
    """Over every step of the sequences ``x`` ``(B, T, F)`` of axes whose true authority is
    ``theta`` ``(B,)``: Huber on the fit's relative error ``(theta_hat - theta) / |theta|`` (the
    closed loop cares about the ratio), plus cross-entropy on the prior's sign and Huber on its
    ``log |theta|`` (so that the guess made before the data speak is as good as it can be)."""
    target = theta[:, None].expand(x.shape[:2])
    logit, log_mag, theta_hat, _ = model.heads(x)
    relative_error = (theta_hat - target) / target.abs().clamp_min(0.05)
    fit = functional.smooth_l1_loss(relative_error, torch.zeros_like(target))
    prior = functional.binary_cross_entropy_with_logits(logit, (target > 0).float())
    return fit + prior + functional.smooth_l1_loss(log_mag, target.abs().clamp_min(0.05).log())


def train_student(request: TrainRequest) -> TrainReport:
    """DAgger-train the student of ``request.controller`` (``rma_student`` or ``rma_dob``)."""
    name, budget = request.controller, BUDGETS[request.budget]
    classes = CLASSES[name]
    config = StudentConfig(
        hidden=budget.hidden,
        latch=LatchConfig(),
        observer_gain=OBSERVER_GAIN if name == "rma_dob" else 0.0,
        bias_invariant=name == "rma_dob",
    )
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
        steps, n_feat = V1.steps, model.inp.in_features
        capacity = budget.buffer_iterations * budget.episodes * 3
        xs = torch.zeros((capacity, steps, n_feat))
        ys = torch.zeros(capacity)
        filled, cursor, loss_avg = 0, 0, float("nan")
        best = (-1.0, copy.deepcopy(model.state_dict()))
        history = []
        for it in range(budget.iterations):
            p_teacher = max(0.0, 1.0 - it / max(1.0, budget.teacher_fraction * budget.iterations))
            episodes = sample_episodes(rng, budget.episodes, "train", classes)
            mask = rng.random(budget.episodes) < p_teacher
            collector = _DaggerController(TorchStudentNet(model), config, mask)
            rollout(collector, episodes)
            x = torch.from_numpy(np.stack(collector.recorded, axis=1))  # (3n, T, F)
            y = torch.from_numpy(episodes.fault.theta.reshape(-1).astype(np.float32))
            idx = (cursor + torch.arange(len(y))) % capacity
            xs[idx], ys[idx] = x, y
            cursor, filled = (cursor + len(y)) % capacity, min(capacity, filled + len(y))
            model.train()
            for _ in range(budget.grad_steps):
                pick = torch.randint(filled, (budget.minibatch,))
                loss = student_loss(model, xs[pick], ys[pick])
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
        train_rate = settled_rate(model, config, classes, V1.n_faults, V1.n_seeds)
    finally:
        torch.set_num_threads(threads)
    out = request.artifact_out()
    save_student(numpy_state(model), config, out)
    wall_s = time.monotonic() - start
    provenance = request.provenance(
        train_rate,
        f"DAgger on train classes {list(classes)}; wall {wall_s:.0f} s on CPU (1 thread); "
        "train_settled_rate = mean settled rate over the pinned train cells of those classes",
    )
    params = {
        "config": config.to_dict(),
        "budget": asdict(budget),
        "history": history,
        "weights_file": Path(out).name,
    }
    save_params(name, params, provenance, Path(out).with_suffix(".yaml"))
    return TrainReport(name, Path(out), train_rate, {"wall_s": wall_s, "history": history})
