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

from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.training.dagger import train_dagger
from scftc_cli.versions.v2.training.rma import student_config
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


class DaggerMission(v3.DaggerMission, StudentMission):
    """v3's DAgger collector on v4's student (the oracle's gains, v4's context); its target, the
    gain in force as it moves, is what v4's creeping and flickering wheels need."""


def train_student(request: TrainRequest) -> TrainReport:
    """DAgger-train v4's student of ``request.controller`` (``rma_student`` or ``rma_dob``)."""
    name, budget = request.controller, BUDGETS[request.budget]
    plan = v3.mission_plan(
        V4,
        CLASSES[name],
        pinned_episodes,
        DaggerMission,
        lambda net, config: StudentMission(net=net, config=config),
    )
    config = dataclasses.replace(student_config(name, budget), dead_below=DEAD_BELOW)
    return train_dagger(request, budget, config, plan)
