"""``e2e_ppo`` on ``scftc-v1``: one recurrent network that must identify the fault and control at once.

Trained from scratch with PPO on the train split (``scftc train --controller e2e_ppo``, which
uses sb3-contrib's ``RecurrentPPO``; ``training/ppo.py``), then exported to plain weights that
the shared deployed form runs (``baselines/policy.py``). The source study used a GRU; sb3-contrib
offers only the LSTM, which is at least as expressive.

Weights: ``weights/e2e_ppo.npz`` of this version's folder, with a sidecar ``e2e_ppo.yaml``.
"""

from __future__ import annotations

from scftc_cli.baselines import policy
from scftc_cli.versions.v1.spec import V1

OBS_SCALE = (1.0, 1.0, 1.0, 10.0, 10.0, 10.0, 1.0, 1.0, 1.0)
"""The policy's input: [sigma, 10 w, previous action] (rates of ~0.1 rad/s to order 1)."""


class E2EPPO(policy.E2EPPO):
    obs_scale = OBS_SCALE
    benchmark = V1.version
