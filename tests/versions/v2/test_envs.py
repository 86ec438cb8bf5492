"""``scftc/AttitudeFTC-v2`` (scftc-v2): registered by ``import scftc_cli`` next to v1 without
a warning, clean under gymnasium's checker, the benchmark's own closed loop to the bit
(observations, true error), the documented reward on the measured state, seeded, same-step
autoreset, and clear errors for bad actions and arguments."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.protocol import Controller
from scftc_cli.registry import make_controller
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v2.controllers.law import AttitudeFuser, split_observation
from scftc_cli.versions.v2.sim.faults import WheelEpisodes
from scftc_cli.versions.v2.sim.testbed import TESTBED
from scftc_cli.versions.v2.spec import V2

gymnasium = pytest.importorskip("gymnasium")
ENV_ID = pytest.importorskip("scftc_cli.versions.v2.envs").ENV_ID
OBS_DIM, ACTION_DIM = V2.obs_dim, V2.action_dim


def _vec(num_envs: int, **kwargs):
    import scftc_cli  # noqa: F401  (registers the environments)

    return gymnasium.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


class Recording(Controller):
    """A controller that keeps every observation it was handed."""

    def __init__(self, inner: Controller) -> None:
        self.inner = inner
        self.seen: list[np.ndarray] = []

    @property
    def privileged(self) -> bool:  # type: ignore[override]
        return self.inner.privileged

    def reset(self, n, context) -> None:
        self.inner.reset(n, context)

    def act(self, obs: np.ndarray) -> np.ndarray:
        self.seen.append(obs.copy())
        return self.inner.act(obs)


def _mixed_episodes() -> WheelEpisodes:
    """Train episodes of every kind: friction and loss faults, an outage, a stuck head."""
    parts = [
        TESTBED.draw("train", "friction", n_faults=2, n_seeds=1),
        TESTBED.draw("train", "loss", n_faults=2, n_seeds=1),
        TESTBED.draw("train", "sign", "st_outage", n_faults=1, n_seeds=1),
        TESTBED.draw("train", "sign", "st_stuck", n_faults=1, n_seeds=1),
    ]
    return WheelEpisodes.concat(parts)


def test_import_scftc_cli_registers_the_v2_environments():
    code = (
        f"import scftc_cli, gymnasium as gym; gym.make({ENV_ID!r}).reset(seed=0); "
        f"gym.make_vec({ENV_ID!r}, num_envs=3, vectorization_mode='vector_entry_point').reset(seed=0)"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"include_prev_action": True, "sensor_faults": (None, *V2.sensor_faults)},
        {"dtype": np.float64, "split": "test"},
    ],
)
def test_checker_passes_without_a_warning(kwargs):
    from gymnasium.utils.env_checker import check_env

    import scftc_cli  # noqa: F401
    from scftc_cli.envs import out_of_date_warning

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no checker warning either
        warnings.filterwarnings("ignore", message=out_of_date_warning(ENV_ID))  # as registration sets it
        check_env(gymnasium.make(ENV_ID, **kwargs).unwrapped)


def test_vector_env_is_the_benchmark_closed_loop_to_the_bit():
    episodes = _mixed_episodes()
    n = episodes.n
    recorder = Recording(make_controller("pd", V2.version))
    run = rollout(recorder, episodes, record=True)
    assert run.commands is not None and run.error_deg is not None
    seen = np.stack(recorder.seen, axis=1)  # (n, steps, 19): what the benchmark's controller saw

    env = _vec(n, dtype=np.float64, include_prev_action=True)
    env32 = _vec(n)
    obs, info = env.reset(seed=0, options={"episodes": episodes})
    obs32, _ = env32.reset(seed=0, options={"episodes": episodes})
    assert info == {} and obs.dtype == np.float64 and obs32.dtype == np.float32
    fuser = AttitudeFuser(n)
    reward = np.full(n, np.nan)
    for k in range(V2.steps):
        assert np.array_equal(obs[:, :OBS_DIM], seen[:, k]), k
        assert np.array_equal(obs32, seen[:, k].astype(np.float32)), k
        heads, valid, gyro, _ = split_observation(obs[:, :OBS_DIM])
        sigma = fuser.update(heads, valid, gyro, V2.dt_s)
        if k:  # the reward of the last step, on the measured state of this observation
            rate = np.linalg.norm(gyro, axis=1)
            error = np.degrees(4.0 * np.arctan(np.sqrt(np.sum(sigma * sigma, axis=1))))
            assert np.allclose(reward, -error / 180.0 - rate + 0.5 * np.exp(-error), rtol=1e-12, atol=0)
        action = run.commands[:, k]
        obs, reward, terminated, truncated, info = env.step(action)
        obs32, *_ = env32.step(action)
        assert set(info) <= {"pointing_error_deg", "final_obs", "_final_obs"}  # never the fault
        assert np.array_equal(info["pointing_error_deg"], run.error_deg[:, k])  # the true error
        assert not terminated.any() and truncated.all() == (k == V2.steps - 1)
        if k < V2.steps - 1:
            assert np.array_equal(obs[:, OBS_DIM:], action)  # the previous action, appended
    assert np.array_equal(info["pointing_error_deg"], run.final_error_deg)


def test_seeded_runs_repeat_and_autoreset_on_the_same_step():
    def fly(seed: int) -> tuple[np.ndarray, dict]:
        env = _vec(4, sensor_faults=(None, "st_bias"))
        obs, _ = env.reset(seed=seed)
        assert obs.shape == (4, OBS_DIM) and obs.dtype == np.float32
        rng = np.random.default_rng(1)
        total = np.zeros(4)
        for _ in range(V2.steps):
            obs, reward, _, truncated, info = env.step(rng.uniform(-1, 1, (4, ACTION_DIM)).astype(np.float32))
            total += reward
        assert truncated.all() and info["_final_obs"].all()
        assert not np.array_equal(info["final_obs"], obs)  # the next episodes already started
        return total, info

    a, info_a = fly(3)
    b, info_b = fly(3)
    assert np.array_equal(a, b) and np.array_equal(info_a["final_obs"], info_b["final_obs"])
    assert not np.array_equal(a, fly(4)[0])

    env = gymnasium.make(ENV_ID)
    first, _ = env.reset(seed=5)
    assert np.array_equal(first, env.reset(seed=5)[0])
    assert not np.array_equal(first, env.reset(seed=6)[0])


def test_observations_stay_inside_the_space_when_the_wheels_hit_their_limit():
    env = _vec(16, dtype=np.float64, fault_classes=("sign",))
    space = env.single_observation_space
    obs, _ = env.reset(seed=2)
    most = np.zeros(16)
    for k in range(V2.steps - 1):
        assert all(space.contains(o) for o in obs), k
        most = np.maximum(most, np.abs(obs[:, 15:19]).max(axis=1))
        full = 1.0 if (k // 80) % 2 else -1.0  # full commands, reversed every 40 s
        obs, *_ = env.step(np.full((16, ACTION_DIM), full))
    assert most.max() > 0.99 * 6000 * 2 * np.pi / 60  # full commands spin wheels to the limit


def test_sensor_faults_reach_the_observation_and_their_onset_is_in_the_train_range():
    env = _vec(8, sensor_faults=("st_outage",))
    obs, _ = env.reset(seed=0)
    assert (obs[:, 9:12] == 1.0).all()
    last_onset = int(V2.splits["train"].onset_s.parts[-1].hi / V2.dt_s)
    for _ in range(last_onset + 1):
        obs, *_ = env.step(np.zeros((8, ACTION_DIM)))
    assert (obs[:, 9:12] == 0.0).all() and (obs[:, :9] == 0.0).all()


@pytest.mark.parametrize("action", [np.zeros(3), np.zeros((1, 4)), np.zeros(5)])
def test_a_wrong_action_shape_is_a_clear_error(action):
    env = gymnasium.make(ENV_ID)
    env.reset(seed=0)
    with pytest.raises(UsageError, match=r"action must have shape \(4,\)"):
        env.step(action)


def test_vector_env_rejects_wrong_shapes_and_non_finite_actions():
    env = _vec(3)
    env.reset(seed=0)
    with pytest.raises(UsageError, match=r"shape \(3, 4\).*got \(3, 3\)"):
        env.step(np.zeros((3, 3)))
    with pytest.raises(UsageError, match="finite"):
        env.step(np.full((3, 4), np.nan))
    with pytest.raises(UsageError, match="3 scftc-v2 episodes"):
        env.reset(options={"episodes": TESTBED.draw("train", "sign", n_faults=2, n_seeds=1)})


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"fault_classes": ("bogus",)}, UnknownNameError),
        ({"split": "validation"}, UnknownNameError),
        ({"sensor_faults": ("st_bais",)}, UnknownNameError),
        ({"fault_classes": ()}, UsageError),
        ({"dtype": np.int32}, UsageError),
        ({"num_envs": 0}, UsageError),
        ({"backend": "basilisk"}, UsageError),
    ],
)
def test_bad_arguments_fail_at_construction(kwargs, error):
    with pytest.raises(error):
        _vec(**({"num_envs": 2} | kwargs))
