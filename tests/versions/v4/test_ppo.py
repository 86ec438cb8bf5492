"""scftc-v4's ``e2e_ppo`` port: v3's policy layout bound to v4 (it refuses v3's episodes), and
v3's trainer on v4's environment writes a policy that flies v4 from its file."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.baselines.checker import check_controller
from scftc_cli.baselines.policy import PolicyConfig
from scftc_cli.versions.v4.controllers.ppo import E2EPPO, OBS_SCALE
from scftc_cli.versions.v4.spec import V4

torch = pytest.importorskip("torch")

from scftc_cli.training.policy import RecurrentPolicy, policy_net  # noqa: E402


def untrained():
    torch.manual_seed(0)
    config = PolicyConfig(lstm_hidden=8, net_arch=(8,))
    return policy_net(RecurrentPolicy(config, len(OBS_SCALE), V4.action_dim).eval(), config)


def test_an_untrained_policy_flies_v4_and_refuses_v3():
    from scftc_cli.errors import UsageError
    from scftc_cli.sim import testbed as testbeds
    from scftc_cli.sim.rollout import rollout

    check_controller(E2EPPO(net=untrained()), benchmark=V4.version)
    with pytest.raises(UsageError, match="flies scftc-v4"):
        rollout(
            E2EPPO(net=untrained()), testbeds.testbed("scftc-v3").draw("train", "gain", n_faults=1, n_seeds=1)
        )


@pytest.mark.slow
def test_a_quick_run_on_v4_writes_a_policy_that_flies_from_its_file(tmp_path, monkeypatch):
    pytest.importorskip("gymnasium")
    import yaml

    from scftc_cli.training import TrainRequest
    from scftc_cli.versions.v4.training import ppo

    monkeypatch.setattr(ppo, "CLASSES", ("nominal", "incipient"))
    out = tmp_path / "e2e_ppo.npz"
    ppo.train_e2e_ppo(
        TrainRequest(controller="e2e_ppo", benchmark=V4.version, seed=0, budget="quick", out=out)
    )
    doc = yaml.safe_load(out.with_suffix(".yaml").read_text())
    assert doc["provenance"]["benchmark_version"] == V4.version
    assert "on scftc-v4 train classes ['nominal', 'incipient']" in doc["provenance"]["notes"]
    check_controller(E2EPPO(path=out), benchmark=V4.version)


def test_the_residual_environment_with_no_correction_flies_pd_exactly():
    pytest.importorskip("gymnasium")
    from scftc_cli.sim.rollout import rollout
    from scftc_cli.versions.v3.controllers.analytic import PD
    from scftc_cli.versions.v4.training.ppo import ResidualVectorEnv

    env = ResidualVectorEnv(2, "train", ("nominal", "double"))
    obs, _ = env.reset(seed=3)
    assert obs.shape == (2, V4.obs_dim + V4.action_dim)
    episodes = env.env.episodes
    errors, rewards = [], []
    for _ in range(V4.steps):
        obs, reward, _, truncated, info = env.step(np.zeros((2, V4.action_dim)))
        errors.append(info["pointing_error_deg"])
        rewards.append(reward)
    assert truncated.all() and info["final_obs"].shape == (2, V4.obs_dim + V4.action_dim)
    flown = rollout(PD(), episodes)
    np.testing.assert_array_equal(errors[-1], flown.final_error_deg)  # the base law, bit for bit
    # the reward pays for pointing near the target and nothing during a slew
    rewards_, errors_ = np.array(rewards), np.array(errors)
    assert ((rewards_ > 0.0) & (rewards_ <= 2.0)).all()
    assert rewards_[errors_ > 20.0].max() < 1e-3 < rewards_[errors_ < 0.1].min()


def test_a_residual_correction_costs_reward():
    pytest.importorskip("gymnasium")
    from scftc_cli.versions.v4.training.ppo import CORRECTION_COST, ResidualVectorEnv

    rewards = []
    for size in (0.0, 1.0):
        env = ResidualVectorEnv(2, "train", ("nominal",))
        env.reset(seed=5)
        _, reward, *_ = env.step(np.full((2, V4.action_dim), size))
        rewards.append(reward)
    # one step of correction barely turns the body: the difference is its cost
    np.testing.assert_allclose(rewards[0] - rewards[1], CORRECTION_COST * V4.action_dim, rtol=1e-9)


def test_an_untrained_residual_policy_stays_within_its_scale_of_pd():
    from scftc_cli.sim import testbed as testbeds
    from scftc_cli.training.recurrent_ppo import ActorCritic
    from scftc_cli.versions.v3.controllers.analytic import PD
    from scftc_cli.versions.v4.controllers.ppo import RESIDUAL_OBS_SCALE, RESIDUAL_SCALE, ResidualPPO

    torch.manual_seed(0)
    config = PolicyConfig(lstm_hidden=8, net_arch=(8,))
    actor = ActorCritic(config, -1.0, len(RESIDUAL_OBS_SCALE), V4.action_dim).actor  # the trainer's start
    residual = ResidualPPO(net=policy_net(actor.eval(), config))
    check_controller(residual, benchmark=V4.version)
    bed = testbeds.testbed(V4.version)
    episodes = bed.draw("train", "sign", n_faults=2, n_seeds=1)
    context = bed.context(episodes, False)
    base = PD()
    residual.reset(2, context)
    base.reset(2, context)
    obs = bed.sensors(episodes).observe(0, bed.plant(episodes, "numpy"))
    step = residual.act(obs) - base.act(obs)
    assert np.all(np.abs(step) <= RESIDUAL_SCALE) and np.abs(step).max() < 0.05 * RESIDUAL_SCALE
