"""Trainers of ``rma_student`` and ``rma_dob`` on ``scftc-v3``: v2's DAgger (``training/dagger.py``)
on v3's train split, flying v3's mission law (``controllers/rma.py``).

Episodes are fresh train draws of the benchmark's own sampler (``envs.sample_episodes``: an
actuator class uniform over ``CLASSES``, then the pinned cells' distribution keyed by random
bytes, never a pinned episode). The teacher's gain, the regression target, is the true wheel
effectiveness in force at each step: healthy before the onset, the fault's gains from it on
(what ``teacher`` allocates through). The classes:

- ``rma_student`` (fits ``y = g a``, no offset model): the classes whose faults are gains alone,
  ``nominal``, ``sign``, ``gain``, ``loss``, ``double`` and ``rod`` (a dead wheel with its rod
  fault), as v2 trains it on its gain classes;
- ``rma_dob`` (bias-invariant, with the offset and friction observer): all eleven actuator
  classes, the friction ones (``friction``, ``intermittent``, ``incipient``) and the offset ones
  (``gain_bias``, ``compound``) included.

The budget is v2's (iterations, episodes, gradient steps); each v3 episode is six times a v2 one.
The buffer keeps only each segment's active prefix (``DaggerPlan.prefixes``: the same loss), which
keeps the 2400-step sequences affordable: about 8 % of the steps are active.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from scftc_cli.baselines.student import StudentNet
from scftc_cli.protocol import Context, Controller
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.training.dagger import DaggerPlan, Recording, train_dagger
from scftc_cli.versions import get_spec
from scftc_cli.versions.v2.controllers.student import LAYOUT, N_FEATURES, StudentConfig
from scftc_cli.versions.v2.training import rma as v2_rma
from scftc_cli.versions.v2.training.rma import student_config
from scftc_cli.versions.v3.controllers.rma import StudentMission
from scftc_cli.versions.v3.envs import sample_episodes
from scftc_cli.versions.v3.sim.faults import AgileEpisodes, pinned_episodes
from scftc_cli.versions.v3.sim.testbed import public_context
from scftc_cli.versions.v3.spec import V3

GAIN_CLASSES = ("nominal", "sign", "gain", "loss", "double", "rod")
CLASSES: dict[str, tuple[str, ...]] = {
    "rma_student": GAIN_CLASSES,
    "rma_dob": tuple(V3.fault_classes),
}
WHEELS = 4
BUDGETS = dict(v2_rma.BUDGETS)
"""v2's budgets (a copy: changing v3's never changes v2's)."""


class DaggerMission(Recording, StudentMission):
    """Training-only (privileged): the student in the loop, except on the episodes of
    ``teacher_mask`` where the true gains in force are allocated through; records what the trainer
    needs. Built on v3's student; a version built on v3's mission subclasses it with its own
    student (whose ``benchmark`` names the spec its context is built for).

    The target is the effectiveness in force at each step (``PlantFault.gain_at``): on v3's faults
    1 before the onset and the fault's gain from it on; on v4's, a creeping gain or a wheel reversed
    inside its bursts as it moves."""

    privileged = True

    def __init__(self, net: StudentNet, config: StudentConfig, teacher_mask: np.ndarray) -> None:
        super().__init__(net=net, config=config)
        self.teacher_mask = teacher_mask[:, None]

    def reset(self, n: int, context: Context) -> None:
        if context.fault is None:
            raise ValueError("the DAgger collector needs the true fault")
        episodes = context.fault.episodes
        self.fault = episodes.fault
        # the student itself never sees the fault
        super().reset(n, public_context(episodes, spec=get_spec(self.benchmark)))
        self.start_recording()

    def gain_hat(self, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        true_gain = self.fault.gain_at(self.k)
        gain = self.estimator.observe(gyro, tach, (self.teacher_mask, true_gain))
        self.record(self.estimator, true_gain)
        return gain


def mission_plan(
    spec: BenchmarkSpec,
    classes: tuple[str, ...],
    pinned: Callable[..., AgileEpisodes],
    collector: Callable[..., Controller],
    deployed: Callable[..., Controller],
) -> DaggerPlan:
    """The DAgger plan of a version flying v3's mission (v3's, v4's): fresh train draws of
    ``classes`` from its sampler ``pinned``, four wheels, v2's student layout, active prefixes."""
    return DaggerPlan(
        spec=spec,
        wheels=WHEELS,
        classes=classes,
        sample=lambda rng, n: sample_episodes(rng, n, "train", classes, pinned=pinned),
        collector=collector,
        deployed=deployed,
        layout=LAYOUT,
        n_features=N_FEATURES,
        prefixes=True,
    )


def train_student(request: TrainRequest) -> TrainReport:
    """DAgger-train v3's student of ``request.controller`` (``rma_student`` or ``rma_dob``)."""
    name, budget = request.controller, BUDGETS[request.budget]
    plan = mission_plan(
        V3,
        CLASSES[name],
        pinned_episodes,
        DaggerMission,
        lambda net, config: StudentMission(net=net, config=config),
    )
    return train_dagger(request, budget, student_config(name, budget), plan)
