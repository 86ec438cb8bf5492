"""``scftc/AttitudeFTC-v3`` (scftc-v3, draft): registered by ``import scftc_cli`` beside v1 and v2,
clean under gymnasium's checker, the benchmark's own closed loop to the bit (observations, true
error to the target), the documented reward on the measured error to the target, fresh episodes
from the benchmark's own sampler (never a pinned one), seeded, same-step autoreset after the whole
mission, and clear errors for bad actions and arguments."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from scftc_cli.envs import out_of_date_warning
from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.registry import make_controller
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v2.controllers.law import AttitudeFuser, split_observation
from scftc_cli.versions.v3.controllers.law import attitude_error
from scftc_cli.versions.v3.sim.faults import AgileEpisodes
from scftc_cli.versions.v3.sim.testbed import TESTBED
from scftc_cli.versions.v3.spec import V3
from tests.versions.v2.test_envs import Recording

gymnasium = pytest.importorskip("gymnasium")
envs = pytest.importorskip("scftc_cli.versions.v3.envs")
ENV_ID, OBS_DIM, ACTION_DIM = envs.ENV_ID, V3.obs_dim, V3.action_dim


def _vec(num_envs: int, **kwargs):
    import scftc_cli  # noqa: F401  (registers the environments)

    return gymnasium.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize(
    "kwargs", [{}, {"include_prev_action": True, "sensor_faults": (None, "st_outage", "mag_spike")}]
)
def test_checker_passes_without_a_warning(kwargs):
    from gymnasium.utils.env_checker import check_env

    import scftc_cli  # noqa: F401

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no checker warning either
        warnings.filterwarnings("ignore", message=out_of_date_warning(ENV_ID))  # as registration sets it
        check_env(gymnasium.make(ENV_ID, **kwargs).unwrapped)


@pytest.mark.slow
def test_vector_env_is_the_benchmark_closed_loop_to_the_bit():
    episodes = AgileEpisodes.concat(
        [
            TESTBED.draw("train", "double", n_faults=1, n_seeds=1),
            TESTBED.draw("train", "rod", n_faults=1, n_seeds=1),
            TESTBED.draw("train", "sign", "st_outage", n_faults=1, n_seeds=1),
        ]
    )
    n = episodes.n
    recorder = Recording(make_controller("pd", V3.version))
    run = rollout(recorder, episodes, record=True)
    assert run.commands is not None and run.error_deg is not None
    seen = np.stack(recorder.seen, axis=1)  # (n, steps, 26): what the benchmark's controller saw

    env = _vec(n, dtype=np.float64, include_prev_action=True)
    obs, info = env.reset(seed=0, options={"episodes": episodes})
    assert info == {} and obs.shape == (n, OBS_DIM + ACTION_DIM)
    fuser = AttitudeFuser(n)
    reward = np.full(n, np.nan)
    for k in range(V3.steps):
        assert np.array_equal(obs[:, :OBS_DIM], seen[:, k]), k
        assert np.all(env.single_observation_space.contains(o.astype(np.float64)) for o in obs)
        heads, valid, gyro, _ = split_observation(obs[:, :OBS_DIM])
        error_mrp = attitude_error(fuser.update(heads, valid, gyro, V3.dt_s), obs[:, 22:25])
        if k:  # the reward of the last step, on the measured error to this observation's target
            rate = np.linalg.norm(gyro, axis=1)
            error = np.degrees(4.0 * np.arctan(np.sqrt(np.sum(error_mrp * error_mrp, axis=1))))
            assert np.allclose(reward, -error / 180.0 - rate + 0.5 * np.exp(-error), rtol=1e-12, atol=0)
        action = run.commands[:, k]
        obs, reward, terminated, truncated, info = env.step(action)
        assert set(info) <= {"pointing_error_deg", "final_obs", "_final_obs"}  # never the fault
        assert np.array_equal(info["pointing_error_deg"], run.error_deg[:, k])  # the true error
        assert not terminated.any() and truncated.all() == (k == V3.steps - 1)
    assert np.array_equal(info["pointing_error_deg"], run.final_error_deg)


def test_fresh_episodes_come_from_the_benchmarks_sampler_and_lie_in_their_split():
    rng = np.random.default_rng(0)
    drawn = envs.sample_episodes(rng, 12, "train", ("gain", "rod"), (None, "mag_bias"))
    assert drawn.n == 12 and set(drawn.fault_class.split("+")) <= {"gain", "rod", "sign"}
    onset_s = np.asarray(drawn.fault.onset_step) * V3.dt_s
    assert np.all(
        V3.splits["train"].onset_s.contains(onset_s) | V3.splits["train"].onset_s.contains(onset_s - V3.dt_s)
    )
    again = envs.sample_episodes(np.random.default_rng(0), 12, "train", ("gain", "rod"), (None, "mag_bias"))
    np.testing.assert_array_equal(drawn.sigma0, again.sigma0)  # seeded
    pinned = TESTBED.draw("train", "gain", n_faults=50, n_seeds=10)
    assert not np.isin(np.asarray(drawn.sigma0)[:, 0], np.asarray(pinned.sigma0)[:, 0]).any()  # never pinned


def test_seeded_runs_repeat_and_autoreset_after_the_whole_mission():
    def fly(seed: int) -> tuple[np.ndarray, dict]:
        env = _vec(3, sensor_faults=(None, "mag_bias"))
        obs, _ = env.reset(seed=seed)
        assert obs.shape == (3, OBS_DIM) and obs.dtype == np.float32
        rng = np.random.default_rng(1)
        total = np.zeros(3)
        for _ in range(V3.steps):
            obs, reward, _, truncated, info = env.step(rng.uniform(-1, 1, (3, ACTION_DIM)).astype(np.float32))
            total += reward
        assert truncated.all() and info["_final_obs"].all()
        assert not np.array_equal(info["final_obs"], obs)  # the next episodes already started
        return total, info

    a, info_a = fly(3)
    b, info_b = fly(3)
    assert np.array_equal(a, b) and np.array_equal(info_a["final_obs"], info_b["final_obs"])
    assert not np.array_equal(a, fly(4)[0])


def test_wrong_actions_and_arguments_are_clear_errors():
    env = gymnasium.make(ENV_ID)
    env.reset(seed=0)
    with pytest.raises(UsageError, match=r"action must have shape \(7,\)"):
        env.step(np.zeros(4))  # v2's action: four wheels, no rods
    vec = _vec(2)
    vec.reset(seed=0)
    with pytest.raises(UsageError, match="finite"):
        vec.step(np.full((2, 7), np.nan))
    with pytest.raises(UsageError, match="2 scftc-v3 episodes"):
        vec.reset(options={"episodes": TESTBED.draw("train", "sign", n_faults=3, n_seeds=1)})
    for kwargs, error in (
        ({"fault_classes": ("bogus",)}, UnknownNameError),
        ({"sensor_faults": ("st_bais",)}, UnknownNameError),
        ({"dtype": np.int32}, UsageError),
        ({"backend": "basilisk"}, UsageError),
    ):
        with pytest.raises(error):
            _vec(2, **kwargs)
