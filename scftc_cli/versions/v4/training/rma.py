"""Trainers of ``rma_student`` and ``rma_dob`` on ``scftc-v4``: v3's DAgger run
(``versions/v3/training/rma.py``) on v4's train split, flying v4's students (``controllers/rma.py``).

What differs from v3: the episodes are v4's fresh train draws (v3's sampler over v4's pinned
distribution, never a pinned episode); the regression target is the true effectiveness in force
at each step *as it moves* (``PlantFault.gain_at``: a creeping gain, a wheel driving backwards
inside its bursts), where v3's target was the fault's constant gain from the onset; the students
fly the law at the oracle's gains and drop a wheel below ``rma.DEAD_BELOW``. The classes are v3's:
``rma_student`` the gain-only ones, ``rma_dob`` all eleven. The budget is v3's (v2's).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from scftc_cli.baselines.student import StudentNet
from scftc_cli.protocol import Context
from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.training.dagger import Recording, train_dagger
from scftc_cli.versions.v2.controllers.student import StudentConfig
from scftc_cli.versions.v2.training.rma import student_config
from scftc_cli.versions.v3.sim.testbed import public_context
from scftc_cli.versions.v3.training import rma as v3
from scftc_cli.versions.v4.controllers.rma import DEAD_BELOW, StudentMission
from scftc_cli.versions.v4.sim.faults import pinned_episodes
from scftc_cli.versions.v4.spec import V4

CLASSES: dict[str, tuple[str, ...]] = {
    "rma_student": v3.GAIN_CLASSES,
    "rma_dob": tuple(V4.fault_classes),
}
BUDGETS = dict(v3.BUDGETS)
"""v3's budgets (a copy: changing v4's never changes v3's)."""


class _DaggerMission(Recording, StudentMission):
    """Training-only (privileged): the student in the loop, except on the episodes of
    ``teacher_mask`` where the true gains in force are allocated through; records what the trainer
    needs."""

    privileged = True
    name = "rma_student"  # the collector is built from a net, never from committed weights

    def __init__(self, net: StudentNet, config: StudentConfig, teacher_mask: np.ndarray) -> None:
        super().__init__(net=net, config=config)
        self.teacher_mask = teacher_mask[:, None]

    def reset(self, n: int, context: Context) -> None:
        if context.fault is None:
            raise ValueError("the DAgger collector needs the true fault")
        episodes = context.fault.episodes
        self.fault = episodes.fault
        super().reset(n, public_context(episodes, spec=V4))  # the student itself never sees the fault
        self.start_recording()

    def gain_hat(self, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        true_gain = self.fault.gain_at(self.k)
        gain = self.estimator.observe(gyro, tach, (self.teacher_mask, true_gain))
        self.record(self.estimator, true_gain)
        return gain


def train_student(request: TrainRequest) -> TrainReport:
    """DAgger-train v4's student of ``request.controller`` (``rma_student`` or ``rma_dob``)."""
    name, budget = request.controller, BUDGETS[request.budget]
    plan = v3.mission_plan(
        V4,
        CLASSES[name],
        pinned_episodes,
        _DaggerMission,
        lambda net, config: StudentMission(net=net, config=config),
    )
    config = dataclasses.replace(student_config(name, budget), dead_below=DEAD_BELOW)
    return train_dagger(request, budget, config, plan)
