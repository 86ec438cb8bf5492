"""Trainer of ``e2e_ppo`` on ``scftc-v2``: the batched recurrent PPO of ``training/recurrent_ppo.py``
on ``scftc/AttitudeFTC-v2`` (episodes of 400 steps), every actuator class of the train split.
"""

from __future__ import annotations

from scftc_cli.errors import ScftcError
from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.training.recurrent_ppo import PPOBudget, PPOPlan, train_recurrent_ppo
from scftc_cli.versions.v2.controllers.ppo import E2EPPO, OBS_SCALE
from scftc_cli.versions.v2.spec import V2

CLASSES = V2.fault_classes

BUDGETS: dict[str, PPOBudget] = {
    "quick": PPOBudget(rollouts=4, n_envs=16, minibatch_envs=8, n_epochs=2, eval_every=2, eval_faults=2),
    # 480 rollouts of 128 episodes: 24.6 M env steps (15 x v1's 1.6 M), 26 min on one torch thread
    # of this 2-core machine (shared with a tuning run)
    "full": PPOBudget(rollouts=480, eval_every=40),
}


def train_e2e_ppo(request: TrainRequest) -> TrainReport:
    """``scftc train --benchmark scftc-v2 --controller e2e_ppo``: PPO from scratch on the train split."""
    try:
        from scftc_cli.versions.v2.envs import AttitudeFTCv2VectorEnv
    except ImportError as err:  # pragma: no cover - depends on the installed extras
        raise ScftcError("training e2e_ppo needs the `rl` extra: pip install 'scftc[rl]'") from err
    plan = PPOPlan(
        spec=V2,
        make_env=AttitudeFTCv2VectorEnv,
        classes=CLASSES,
        obs_scale=OBS_SCALE,
        deployed=lambda net: E2EPPO(net=net),
    )
    return train_recurrent_ppo(request, BUDGETS[request.budget], plan)
