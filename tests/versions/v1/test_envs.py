"""The gymnasium environments: registered by ``import scftc_cli`` (either import order), checked
by gymnasium's own checkers, seeded, same-step autoreset, on the fused kernel, and the fast batch
sampler drawing from the same distribution as the per-episode one."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.stats import ks_2samp

from scftc_cli.versions.v1.sim.faults import sample_episodes, sample_episodes_batch
from scftc_cli.versions.v1.spec import V1

gymnasium = pytest.importorskip("gymnasium")
ENV_ID = "scftc/AttitudeFTC-v1"


@pytest.mark.parametrize(
    "code",
    [
        f"import gymnasium as gym, scftc_cli; gym.make({ENV_ID!r}).reset(seed=0)",
        f"import scftc_cli, gymnasium as gym; gym.make({ENV_ID!r}).reset(seed=0)",
        "import scftc_cli, gymnasium as gym; "
        f"gym.make_vec({ENV_ID!r}, num_envs=3, vectorization_mode='vector_entry_point').reset(seed=0)",
    ],
)
def test_import_scftc_cli_registers_the_environments(code: str):
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_v1_is_not_called_out_of_date_by_the_v2_track():
    """Gymnasium reads ``-v2`` as v1's successor and prints "out of date" on ``make`` of v1; the
    tracks are separate, so nothing is printed."""
    code = (
        "import scftc_cli, gymnasium as gym; "
        f"gym.make({ENV_ID!r}); gym.make('scftc/AttitudeFTC-v2'); "
        f"gym.make_vec({ENV_ID!r}, num_envs=2, vectorization_mode='vector_entry_point')"
    )
    done = subprocess.run(
        [sys.executable, "-W", "default", "-c", code], check=True, timeout=120, capture_output=True, text=True
    )
    assert "out of date" not in done.stderr, done.stderr


def test_checkers_pass():
    from gymnasium.utils.env_checker import check_env

    import scftc_cli  # noqa: F401
    from scftc_cli.envs import out_of_date_warning

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no checker warning either
        warnings.filterwarnings("ignore", message=out_of_date_warning(ENV_ID))  # as registration sets it
        check_env(gymnasium.make(ENV_ID).unwrapped)
        check_env(gymnasium.make(ENV_ID, include_prev_action=True).unwrapped)


def _run(seed: int, num_envs: int = 5, **kwargs) -> tuple[np.ndarray, dict]:
    env = gymnasium.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
    obs, _ = env.reset(seed=seed)
    assert obs.shape == (num_envs, 6) and obs.dtype == np.float32
    total = np.zeros(num_envs)
    for k in range(V1.steps):
        obs, reward, terminated, truncated, info = env.step(np.full((num_envs, 3), 0.1, dtype=np.float32))
        total += reward
        assert not terminated.any()
        assert truncated.all() == (k == V1.steps - 1)
    assert "final_obs" in info and info["_final_obs"].all()
    assert not np.array_equal(info["final_obs"], obs)  # the same step already holds the next episodes
    return total, info


def test_vector_env_matches_the_horizon_is_seeded_and_autoresets_on_the_same_step():
    a, _ = _run(3)
    b, _ = _run(3)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, _run(4)[0])


def test_the_fused_kernel_and_the_numpy_plant_give_the_same_rewards():
    fused, _ = _run(7, num_envs=6, backend="numpy")
    reference, _ = _run(7, num_envs=6, backend="reference")
    assert np.array_equal(fused, reference)


def test_batch_sampler_draws_the_same_distribution_as_the_per_episode_one():
    classes = ("sign", "gain", "gain_bias", "loss")
    one = sample_episodes(np.random.default_rng(0), 4000, "train", classes)
    batch = sample_episodes_batch(np.random.default_rng(1), 4000, "train", classes)
    split = V1.splits["train"]
    for e in (one, batch):
        f = e.fault
        assert np.all(split.inertia_scale.contains(f.inertia_scale))
        assert set(np.unique(np.sum(f.gain < 0, axis=1))) <= set(split.reversed_axes)
        alive = f.gain != 0
        assert np.all(split.gain_magnitude.contains(np.abs(f.gain[alive])) | (np.abs(f.gain[alive]) == 1.0))
    for get in (
        lambda e: e.fault.inertia_scale,
        lambda e: np.sum(e.fault.gain < 0, axis=1),
        lambda e: np.sum(e.fault.gain == 0, axis=1),
        lambda e: np.abs(e.fault.gain[e.fault.gain != 0]),
        lambda e: e.fault.bias[e.fault.bias != 0],
        lambda e: (e.fault.gain < 0).argmax(axis=1)[np.sum(e.fault.gain < 0, axis=1) == 1],
        lambda e: e.sigma0[:, 0],
    ):
        assert ks_2samp(get(one), get(batch)).pvalue > 1e-3
