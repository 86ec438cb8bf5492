"""Trainer of ``e2e_ppo`` on ``scftc-v3``: the batched recurrent PPO of ``training/recurrent_ppo.py``
(v2's, unchanged) on ``scftc/AttitudeFTC-v3``, every actuator class of the train split (no sensor
class drawn; ``compound`` episodes carry their companion sensor fault, as in the benchmark).

The budget gives the run v2's experience in env steps: 80 rollouts of 128 whole v3 episodes (2400
steps each) are 24.6 M env steps, as v2's 480 rollouts of 400-step episodes. Each rollout is six
times longer, so a gradient epoch backpropagates through 2400 steps.
"""

from __future__ import annotations

from scftc_cli.errors import ScftcError
from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.training.recurrent_ppo import PPOBudget, PPOPlan, train_recurrent_ppo
from scftc_cli.versions.v3.controllers.ppo import E2EPPO, OBS_SCALE
from scftc_cli.versions.v3.spec import V3

CLASSES = V3.fault_classes

BUDGETS: dict[str, PPOBudget] = {
    "quick": PPOBudget(
        rollouts=2, n_envs=8, minibatch_envs=4, n_epochs=1, eval_every=2, eval_faults=1, eval_seeds=1
    ),
    "full": PPOBudget(rollouts=80, eval_every=8),
}


def train_e2e_ppo(request: TrainRequest) -> TrainReport:
    """``scftc train --benchmark scftc-v3 --controller e2e_ppo``: PPO from scratch on the train split."""
    try:
        from scftc_cli.versions.v3.envs import AttitudeFTCv3VectorEnv
    except ImportError as err:  # pragma: no cover - depends on the installed extras
        raise ScftcError("training e2e_ppo needs the `rl` extra: pip install 'scftc[rl]'") from err
    plan = PPOPlan(
        spec=V3,
        make_env=AttitudeFTCv3VectorEnv,
        classes=CLASSES,
        obs_scale=OBS_SCALE,
        deployed=lambda net: E2EPPO(net=net),
    )
    return train_recurrent_ppo(request, BUDGETS[request.budget], plan)
