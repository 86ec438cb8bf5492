"""Trainers of ``rma_student`` and ``rma_dob`` on ``scftc-v2``: DAgger on the train split
(``training/dagger.py``, shared with v3).

As on v1 (``versions/v1/training/rma.py``): each iteration flies a fresh batch of train-split
episodes (``sample_episodes_batch``) with the student's own latched estimate in the loop (mixed,
early on, with episodes allocated through the teacher's true ``g(t)``); the student's
least-squares fit regresses the true effectiveness in force at every step on which the network
ran. ``rma_dob``'s student flies with its offset and friction observer in the loop and reads only
bias-invariant features. Nothing here sees the test split; the checkpoint kept is the best on
pinned *train* cells.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.baselines.student import StudentNet
from scftc_cli.protocol import Context
from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.training.dagger import DaggerPlan, Recording, train_dagger
from scftc_cli.training.student import RMABudget
from scftc_cli.versions.v2.controllers.rma import StudentController
from scftc_cli.versions.v2.controllers.student import LAYOUT, N_FEATURES, StudentConfig
from scftc_cli.versions.v2.sim.faults import sample_episodes_batch
from scftc_cli.versions.v2.sim.testbed import public_context
from scftc_cli.versions.v2.spec import V2

CLASSES = {
    "rma_student": ("sign", "gain", "loss"),
    "rma_dob": ("sign", "gain", "gain_bias", "friction", "loss"),
}

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


class _DaggerController(Recording, StudentController):
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
        self.start_recording()

    def gain_hat(self, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        true_gain = self.fault.at(self.k)[0]
        gain = self.estimator.observe(gyro, tach, (self.teacher_mask, true_gain))
        self.k += 1
        self.record(self.estimator, true_gain)
        return gain


def student_config(name: str, budget: RMABudget) -> StudentConfig:
    """The deployment settings of ``name``: ``rma_dob`` is bias-invariant with the observer."""
    dob = name == "rma_dob"
    return StudentConfig(hidden=budget.hidden, bias_invariant=dob, observer=dob)


def train_student(request: TrainRequest) -> TrainReport:
    """DAgger-train the student of ``request.controller`` (``rma_student`` or ``rma_dob``)."""
    name, budget = request.controller, BUDGETS[request.budget]
    classes = CLASSES[name]
    plan = DaggerPlan(
        spec=V2,
        wheels=V2.action_dim,
        classes=classes,
        sample=lambda rng, n: sample_episodes_batch(rng, n, "train", classes),
        collector=_DaggerController,
        deployed=lambda net, config: StudentController(net=net, config=config),
        layout=LAYOUT,
        n_features=N_FEATURES,
    )
    return train_dagger(request, budget, student_config(name, budget), plan)
