"""``rma_student`` and ``rma_dob`` on ``scftc-v4``: v3's students on the mission law
(``versions/v3/controllers/rma.py``: v2's per-wheel GRU estimate of each wheel's effectiveness,
latched, re-opened on a change; ``rma_dob`` with the offset and friction observer), with two
things of v4's own:

- the law's PD gains are the oracle's, tuned on v4's train split (``analytic.LawGains``,
  ``params/oracle.yaml`` of this version); v3 flew its students at v2's gains;
- a wheel counts as dead below ``DEAD_BELOW`` (v2's students drop it below 0.1, which reads
  v4's weakest working wheels, 0.025 of their torque on ``double``'s train split, as dead and
  leaves two wheels to fly three axes).

The weights are v4's own, trained on v4's train split (``training/rma.py``): ``weights/rma_student.npz``
and ``weights/rma_dob.npz`` of this version with their ``.yaml``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from scftc_cli.baselines.params import committed_params
from scftc_cli.baselines.student import StudentNet
from scftc_cli.versions.v2.controllers.student import StudentConfig
from scftc_cli.versions.v3.controllers import rma as v3
from scftc_cli.versions.v3.controllers.fused import rate_limited_demand
from scftc_cli.versions.v4.controllers import analytic
from scftc_cli.versions.v4.spec import V4

DEAD_BELOW = 0.0125
"""Half of the weakest gain a working wheel has on v4's train split (0.025, ``double``): a latched
estimate below it is allocated as a dead wheel."""


def law_gains() -> analytic.LawGains:
    """The mission law's PD gains every v4 student flies: the oracle's committed ones."""
    return analytic.LawGains(**committed_params(*analytic.TunedLaw.tuned_as))


class StudentMission(v3.StudentMission):
    """v3's student mission law at the oracle's gains, with v4's weights."""

    benchmark = V4.version

    def __init__(
        self, path: Path | None = None, net: StudentNet | None = None, config: StudentConfig | None = None
    ) -> None:
        super().__init__(path, net, config)
        self.gains = law_gains()  # read once, not at every reset

    def demand(self, error: np.ndarray, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        return rate_limited_demand(error, gyro, tach, self.context, self.gains.kp_s2, self.gains.kd_s)


class RMAStudent(StudentMission):
    """The RMA student; weights: this version's ``weights/rma_student.npz``."""

    name = "rma_student"


class RMADob(StudentMission):
    """The bias-invariant student with the per-wheel offset and friction observer; weights: this
    version's ``weights/rma_dob.npz``."""

    name = "rma_dob"
