"""``rma_student`` and ``rma_dob`` on ``scftc-v3``: v2's per-wheel RMA students flying the mission
law (``analytic.MissionLaw``).

The estimator is v2's, unchanged (``versions/v2/controllers/rma.py``, ``WheelEstimator``): one GRU,
shared by the four wheels, reads each wheel's history of commands and measured torques and reports
its effectiveness ``g_hat``, a persistence-of-excitation latch freezes it, a CUSUM test on the
innovation re-opens it when a fault starts, comes back or creeps in; ``rma_dob``'s student reads
only bias-invariant features and a per-wheel observer estimates the offset and the extra Coulomb
friction. The wheel measurement (tachometers and gyro, ``Js (dOmega + g . dw)``) is the wheel's own
equation: the environment's and the rods' torques act on the hub, not between hub and wheel, so
v2's features and estimator carry over to v3 as they are. Only the weights are v3's own, trained
on v3's train split (``training/rma.py``).

What the mission law gets from it: the latched gains (the weakest wheel allocated as dead below
``dead_below``, every other kept that far from zero, ``student_effective_gain``) and, for
``rma_dob``, the observer's offsets and Coulomb levels (``wheel_model``). The rods unload as in
``pd`` (nothing is estimated of them), and the null-space drain runs through the estimated gains.
It reports no diagnosis (``health`` returns ``None``: scored as never alarming).

Weights: ``weights/rma_student.npz`` and ``weights/rma_dob.npz`` of this version with their
``.yaml`` (provenance); ``scftc train --benchmark scftc-v3 --controller rma_student|rma_dob``
regenerates them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from scftc_cli.baselines import student
from scftc_cli.baselines.params import committed_weights
from scftc_cli.baselines.student import StudentNet
from scftc_cli.protocol import Context
from scftc_cli.versions.v2.controllers.law import friction_nm
from scftc_cli.versions.v2.controllers.rma import WheelEstimator, student_effective_gain
from scftc_cli.versions.v2.controllers.student import LAYOUT, StudentConfig
from scftc_cli.versions.v3.controllers.analytic import MissionLaw
from scftc_cli.versions.v3.controllers.law import split_observation
from scftc_cli.versions.v3.spec import V3


def load_student(
    name: str, path: Path | None = None, benchmark: str = V3.version
) -> tuple[StudentNet, StudentConfig]:
    """``benchmark``'s committed student ``name`` (or the one at ``path``; v3's by default), ready for
    the kernel (float64)."""
    return student.load_student(path or committed_weights(name, benchmark), LAYOUT, StudentConfig)


class StudentMission(MissionLaw):
    """The mission law allocated through the student's latched per-wheel gains, with (``rma_dob``)
    the observer's offsets and extra friction cancelled per wheel."""

    name = "rma_student"
    benchmark = V3.version  # whose committed weights it loads (a version built on v3's mission: its own)

    def __init__(
        self, path: Path | None = None, net: StudentNet | None = None, config: StudentConfig | None = None
    ) -> None:
        if net is None or config is None:
            net, config = load_student(self.name, path, self.benchmark)
        self.net, self.config = net, config

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        self.estimator = WheelEstimator(self.net, self.config, context)
        self.gain = np.ones((n, self.m))

    def gain_hat(self, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        """The ``(n, m)`` gains the law allocates through (the trainer mixes in the true ones)."""
        return self.estimator.observe(gyro, tach)

    def wheel_model(self, tach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        offset = self.estimator.offset()
        # as v2's: b + d psi is used as estimated (not clamped), friction_nm is linear in the level
        coulomb = self.wheels.coulomb_nm + offset[..., 1] * self.wheels.u_max_nm
        effective = student_effective_gain(self.gain, self.config.dead_below)
        return effective, offset[..., 0], friction_nm(tach, coulomb, self.wheels)

    def act(self, obs: np.ndarray) -> np.ndarray:
        _, _, gyro, tach, *_ = split_observation(obs)
        self.gain = self.gain_hat(gyro, tach)
        offset = self.estimator.offset()
        command = super().act(obs)
        self.estimator.hold(command[:, : self.m], offset)
        return command


class RMAStudent(StudentMission):
    """The RMA student; weights: this version's ``weights/rma_student.npz``."""

    name = "rma_student"


class RMADob(StudentMission):
    """The bias-invariant student with the per-wheel offset and friction observer; weights: this
    version's ``weights/rma_dob.npz``."""

    name = "rma_dob"
