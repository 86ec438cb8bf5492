"""scftc-v3's ``e2e_ppo``: v2's batched recurrent PPO on the v3 environment (33 inputs: the 26
readings and the previous 7 commands). The untrained policy flies the protocol; a quick run writes
its weights and provenance, and the deployed kernel is the torch actor."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from scftc_cli.baselines.checker import check_controller
from scftc_cli.baselines.policy import PolicyConfig
from scftc_cli.versions.v3.controllers.ppo import ACTIONS, E2EPPO, OBS_SCALE
from scftc_cli.versions.v3.spec import V3

torch = pytest.importorskip("torch")

from scftc_cli.training.policy import RecurrentPolicy, policy_net  # noqa: E402


def test_the_input_is_the_observation_and_the_previous_command():
    assert len(OBS_SCALE) == V3.obs_dim + V3.action_dim and ACTIONS == 7


def test_an_untrained_policy_flies_the_protocol_and_refuses_another_version():
    from scftc_cli.errors import UsageError
    from scftc_cli.sim import testbed as testbeds
    from scftc_cli.sim.rollout import rollout

    torch.manual_seed(0)
    config = PolicyConfig(lstm_hidden=8, net_arch=(8,))
    net = policy_net(RecurrentPolicy(config, len(OBS_SCALE), ACTIONS).eval(), config)
    check_controller(E2EPPO(net=net), benchmark=V3.version)
    with pytest.raises(UsageError):
        rollout(E2EPPO(net=net), testbeds.testbed("scftc-v2").draw("train", "gain", n_faults=1, n_seeds=1))


@pytest.mark.slow
def test_a_quick_run_writes_a_policy_whose_export_the_trainer_checked(tmp_path, monkeypatch):
    pytest.importorskip("gymnasium")
    from scftc_cli.baselines import recurrent
    from scftc_cli.training import TrainRequest
    from scftc_cli.versions.v3.training import ppo

    monkeypatch.setattr(ppo, "CLASSES", ("nominal", "loss"))
    out = tmp_path / "e2e_ppo.npz"
    report = ppo.train_e2e_ppo(
        TrainRequest(controller="e2e_ppo", benchmark=V3.version, seed=0, budget="quick", out=out)
    )
    assert report.artifact == out and 0.0 <= report.train_settled_rate <= 1.0
    arrays, config = recurrent.load_weights(out)
    assert all(np.all(np.isfinite(a)) for a in arrays.values())
    doc = yaml.safe_load(out.with_suffix(".yaml").read_text())
    assert doc["params"]["export_max_abs_diff"] <= 1e-4  # the trainer's own check of the export
    assert doc["params"]["budget"]["env_steps"] == 2 * 8 * V3.steps
    assert "on scftc-v3 train classes ['nominal', 'loss']" in doc["provenance"]["notes"]
    E2EPPO(path=out)  # loads as the deployed controller
