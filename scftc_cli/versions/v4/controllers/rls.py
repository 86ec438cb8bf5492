"""``rls_dob`` on ``scftc-v4``: v3's estimate-then-control port (``versions/v3/controllers/rls.py``:
v2's per-wheel RLS and disturbance observer on the mission law), tuned on v4's train split from
v3's settings, with two more things tuned: the PD gains of its law (v3 kept v2's) and the gain
below which it counts a wheel dead and drops it from the allocation (v2's estimators fix it at
0.1, which reads v4's weak wheels, 0.025 to 0.07 of their torque, as dead and leaves two wheels).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.versions.v2.controllers.estimators import DEAD_BELOW
from scftc_cli.versions.v2.controllers.law import friction_nm
from scftc_cli.versions.v2.controllers.rls import RLSParams
from scftc_cli.versions.v3.controllers import rls as v3
from scftc_cli.versions.v4.spec import V4

NAME = v3.NAME


@dataclass(frozen=True)
class V4RLSParams(RLSParams):
    """v2's ``RLSParams`` plus ``dead_below``: a wheel whose estimated gain magnitude is below it is
    dropped from the allocation (exactly 0), as v2's ``effective_gain`` does at ``DEAD_BELOW``."""

    dead_below: float = DEAD_BELOW


class RLSDob(v3.RLSDob):
    """v3's ``rls_dob`` with its dead-wheel threshold a setting, and v4's committed parameters
    (``params/rls_dob.yaml`` of this version)."""

    params_type = V4RLSParams
    tuned_as = (NAME, V4.version)
    params: V4RLSParams

    def wheel_model(self, tach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        g_hat, b_hat, kappa_hat = self.estimates
        gain = np.where(np.abs(g_hat) < self.params.dead_below, 0.0, g_hat)
        friction = friction_nm(tach, kappa_hat * self.wheels.u_max_nm, self.wheels)
        return gain, np.where(gain == 0.0, 0.0, b_hat), friction
