"""``e2e_ppo`` on ``scftc-v2``: one recurrent network that must fuse the sensors, identify the fault
and allocate the four wheels at once.

Trained from scratch with PPO on the train split of the gymnasium environment
``scftc/AttitudeFTC-v2`` (``training/ppo.py``: a batched PPO written for the vector
environment, which steps every episode as one call of the fused kernel), then exported to the
actor layout v1's policy has, which the shared deployed form runs (``baselines/policy.py``): an
LSTM over the scaled observation and the previous action, one tanh layer, a linear action head.

Weights: ``weights/e2e_ppo.npz`` of this version's folder, with a sidecar ``e2e_ppo.yaml``.
"""

from __future__ import annotations

from scftc_cli.baselines import policy
from scftc_cli.protocol import Context
from scftc_cli.versions.v2.controllers.law import wheels_of
from scftc_cli.versions.v2.spec import V2

ACTIONS = V2.action_dim
OBS_SCALE = (1.0,) * 12 + (20.0,) * 3 + (1.0 / 600.0,) * 4 + (1.0,) * ACTIONS
"""The policy's input: [3 head MRPs, 3 validity flags, 20 x gyro, tachometers / 600 rad/s, previous
action] (rates of ~0.05 rad/s and wheel speeds of up to ~600 rad/s to order 1)."""


class E2EPPO(policy.E2EPPO):
    obs_scale = OBS_SCALE
    benchmark = V2.version

    def reset(self, n: int, context: Context) -> None:
        wheels_of(context)  # a clear error on a version without reaction wheels
        super().reset(n, context)
