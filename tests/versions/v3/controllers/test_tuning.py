"""scftc-v3's tuned ports (``pid``, ``rls_dob``) read their parameters per episode, so a tuner flies
a generation's candidates as one batch: each candidate must score exactly as it would alone, and
sit on its own rows."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from scftc_cli.baselines.checker import check_controller
from scftc_cli.registry import controller_spec
from scftc_cli.training import get_trainer, tuning
from scftc_cli.versions.v3.spec import V3
from scftc_cli.versions.v3.training.tuning import SPECS

CELLS = {"pid": ("gain", "nominal", "sign+gyro_bias"), "rls_dob": ("gain", "loss", "nominal")}


@pytest.mark.parametrize("name", ["pid", pytest.param("rls_dob", marks=pytest.mark.slow)])
def test_a_generation_flown_as_one_batch_scores_every_candidate_as_alone(name):
    spec = SPECS[name]
    assert spec.per_episode_params
    episodes = tuning.tuning_episodes(1, 1, CELLS[name], "scftc-v3")
    rng = np.random.default_rng(3)
    low, high = np.array([d.bounds() for d in spec.space]).T
    xs = low[:, None] + (high - low)[:, None] * rng.uniform(size=(len(spec.space), 3))
    xs[:, 0] = spec.start()  # the documented values among them
    batch, rates = tuning.population_losses(spec, xs, episodes)
    alone = [tuning.objective(spec.factory(spec.params(xs[:, j])), episodes) for j in range(3)]
    np.testing.assert_array_equal(batch, [a[0] for a in alone])  # the same bits, candidate by candidate
    np.testing.assert_array_equal(rates, [a[1] for a in alone])
    assert len(set(batch)) == 3  # the candidates really differ, so rows were not mixed up unnoticed


def test_the_population_puts_each_candidate_on_its_own_rows():
    spec = SPECS["rls_dob"]  # integer dimensions among them
    xs = np.array([[d.bounds()[0], d.bounds()[1]] for d in spec.space])
    params = spec.population(xs, repeats=3)
    for j in range(2):
        alone = spec.params(xs[:, j])
        for d in spec.space:
            column = getattr(params, d.name)
            assert column.shape == (6, 1)
            np.testing.assert_array_equal(column[3 * j : 3 * j + 3, 0], getattr(alone, d.name))


@pytest.mark.parametrize("name", ["pid", "rls_dob"])
def test_the_tuned_ports_are_registered_with_their_committed_params_and_provenance(name):
    entry = controller_spec(name, V3.version)
    assert entry.artifacts == (f"params/v3/{name}.yaml",)
    (path,) = entry.artifact_paths()
    doc = yaml.safe_load(path.read_text())  # committed: a missing file fails here
    assert doc["controller"] == name and doc["provenance"]["benchmark_version"] == V3.version
    assert doc["provenance"]["budget"] == "full" and doc["provenance"]["seed"] == 0
    assert get_trainer(name, V3.version).__module__ == "scftc_cli.training.tuning"
    check_controller(entry.make(), benchmark=V3.version, steps=10, classes=("sign",))
