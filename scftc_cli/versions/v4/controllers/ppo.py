"""``e2e_ppo`` and ``residual_ppo`` on ``scftc-v4``.

``e2e_ppo``: v3's end-to-end recurrent policy (``versions/v3/controllers/ppo.py``:
an LSTM over the 26 scaled readings and the previous action, one tanh layer, a linear head for the
four wheels and three rods), the same layout and input scaling, its weights trained on v4's train
split (``training/ppo.py``): ``weights/e2e_ppo.npz`` of this version with its ``.yaml``. It reports
no diagnosis.

``residual_ppo`` (``ResidualPPO``): learning at its best rather than from scratch, a recurrent
policy that corrects the fault-unaware mission law's command (``weights/residual_ppo.npz``).
"""

from __future__ import annotations

import numpy as np

from scftc_cli.protocol import Context
from scftc_cli.versions.v3.controllers import ppo as v3
from scftc_cli.versions.v3.controllers.analytic import PD
from scftc_cli.versions.v4.spec import V4

OBS_SCALE = v3.OBS_SCALE


class E2EPPO(v3.E2EPPO):
    benchmark = V4.version


RESIDUAL_SCALE = 0.2
"""The largest correction the residual policy adds to each command, as a fraction of that
actuator's limit: enough to re-balance a weak or reversed wheel's share, small enough that the
untrained policy (an action head initialised at 0.01 of a unit) flies the base law."""
RESIDUAL_OBS_SCALE = v3.OBS_SCALE[: V4.obs_dim] + (1.0,) * V4.action_dim + (1.0,) * V4.action_dim
"""The residual policy's input: the 26 readings scaled as ``e2e_ppo``'s, the base law's command
(already in [-1, 1]) and the previous correction."""


class ResidualPPO(E2EPPO):
    """``pd``'s mission law (v3's fault-unaware law, ``analytic.PD``) plus a learned recurrent
    correction: ``command = clip(base + RESIDUAL_SCALE * clip(policy(readings, base, previous
    correction)), -1, 1)``. The policy is ``e2e_ppo``'s layout with the base command among its
    inputs; trained by PPO on v4's train split with the base inside the environment's step
    (``training/ppo.py``). It reports no diagnosis."""

    name = "residual_ppo"
    obs_scale = RESIDUAL_OBS_SCALE

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        self.base = PD()
        self.base.reset(n, context)

    def act(self, obs: np.ndarray) -> np.ndarray:
        base = self.base.act(obs)
        correction = super().act(np.concatenate((obs, base), axis=1))
        return np.clip(base + RESIDUAL_SCALE * correction, -1.0, 1.0)
