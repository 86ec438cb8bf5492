"""Trainer of ``e2e_ppo`` on ``scftc-v4``: v3's run (``versions/v3/training/ppo.py``: the batched
recurrent PPO of ``training/recurrent_ppo.py`` from scratch, v3's budgets) on
``scftc/AttitudeFTC-v4``, every actuator class of v4's train split (no sensor class drawn;
``compound`` episodes carry their companion sensor fault, as in the benchmark).
"""

from __future__ import annotations

from scftc_cli.errors import ScftcError
from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.training.recurrent_ppo import PPOPlan, train_recurrent_ppo
from scftc_cli.versions.v3.training import ppo as v3
from scftc_cli.versions.v4.controllers.ppo import E2EPPO, OBS_SCALE
from scftc_cli.versions.v4.spec import V4

CLASSES = V4.fault_classes
BUDGETS = dict(v3.BUDGETS)
"""v3's budgets (a copy: changing v4's never changes v3's)."""


def train_e2e_ppo(request: TrainRequest) -> TrainReport:
    """``scftc train --benchmark scftc-v4 --controller e2e_ppo``: PPO from scratch on the train split."""
    try:
        from scftc_cli.versions.v4.envs import AttitudeFTCv4VectorEnv
    except ImportError as err:  # pragma: no cover - depends on the installed extras
        raise ScftcError("training e2e_ppo needs the `rl` extra: pip install 'scftc[rl]'") from err
    plan = PPOPlan(
        spec=V4,
        make_env=AttitudeFTCv4VectorEnv,
        classes=CLASSES,
        obs_scale=OBS_SCALE,
        deployed=lambda net: E2EPPO(net=net),
    )
    return train_recurrent_ppo(request, BUDGETS[request.budget], plan)
