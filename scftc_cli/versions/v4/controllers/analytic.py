"""``teacher`` and ``oracle`` on ``scftc-v4``: v3's privileged controllers
(``versions/v3/controllers/analytic.py``) flying the mission law at PD gains tuned on v4's train
split.

v3 flew them at v2's gains (``kp_s2`` 0.04, ``kd_s`` 0.14), chosen for v2's 200 s hold; on v4's
train split the train-tuned ``rls_dob`` (gains 0.34 and 2.4) settled more of ``double`` and
``incipient`` than the oracle, which therefore was no upper bound there. Here the two gains are
the oracle's own tuned parameters (``params/oracle.yaml`` of this version, ``scftc train
--benchmark scftc-v4 --controller oracle``), and the teacher flies the same ones: the learned
ports' teacher knows what the oracle knows of the wheels, at the oracle's gains.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.versions.v2.controllers.law import KD_S, KP_S2
from scftc_cli.versions.v3.controllers import analytic as v3
from scftc_cli.versions.v3.controllers.fused import rate_limited_demand
from scftc_cli.versions.v4.spec import V4

NAME = "oracle"


@dataclass(frozen=True)
class LawGains:
    """The mission law's PD gains: ``kp_s2`` (1/s^2) and ``kd_s`` (1/s), scalars or ``(n, 1)`` arrays
    (one value per episode, as the tuner flies a generation). Defaults: v2's, which v3 flew."""

    kp_s2: float | np.ndarray = KP_S2
    kd_s: float | np.ndarray = KD_S


class TunedLaw(Tuned):
    """Mixin: the mission law's demand at the tuned ``LawGains``."""

    params_type = LawGains
    tuned_as = (NAME, V4.version)
    params: LawGains

    def demand(self, error: np.ndarray, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        p = self.params
        return rate_limited_demand(error, gyro, tach, self.context, p.kp_s2, p.kd_s)  # type: ignore[attr-defined]


class Teacher(TunedLaw, v3.Teacher):
    """v3's teacher (the true ``g(t)`` and rod gains, a perfect diagnosis) at the oracle's gains."""


class Oracle(TunedLaw, v3.Oracle):
    """v3's oracle (the teacher plus offsets, friction, environment, field and sensor faults) at its
    tuned gains."""
