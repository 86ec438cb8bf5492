"""A tuning run's journal: losses stored to the bit and read back, a line cut by a crash ignored,
a stopped run resumed to exactly the uninterrupted result without flying its candidates again,
and a generation that flies only the candidates the journal lacks."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from scftc_cli.protocol import NO_PROGRESS, Progress
from scftc_cli.training import TrainRequest, tuning
from scftc_cli.training.journal import EvaluationJournal, journal_path
from scftc_cli.versions.v1.training import tuning as v1_tuning
from scftc_cli.versions.v3.training import tuning as v3_tuning


def test_losses_come_back_to_the_bit_and_a_line_cut_by_a_crash_is_ignored(tmp_path):
    path = tmp_path / "j.jsonl"
    journal = EvaluationJournal(path)
    xs = [np.array([0.1 + 0.2, 1e-300, -3.0]), np.array([np.pi, 2.0, 5.0])]
    journal.record(xs, [(-0.7 + 1e-17, 0.7), (-1.0 / 3.0, 1.0 / 3.0)])
    with path.open("a") as handle:
        handle.write('{"x": ["0x1.0p+0"], "loss": "0x1.')  # the crash
    again = EvaluationJournal(path)
    assert again.resumed == 2
    assert again.get(xs[0]) == (-0.7 + 1e-17, 0.7)
    assert again.get(xs[1]) == (-1.0 / 3.0, 1.0 / 3.0)
    assert again.get(np.array([0.3, 1e-300, -3.0])) is None  # 0.1 + 0.2 is not 0.3
    again.close()
    assert not path.exists()


class _StopAfter(Progress):
    """Stops the run (as Ctrl-C would) after ``n`` evaluations were reported."""

    def __init__(self, n: int) -> None:
        self.n, self.seen = n, 0

    def describe(self, text: str) -> None:
        if text.startswith("eval "):
            self.seen += 1
            if self.seen >= self.n:
                raise KeyboardInterrupt


def test_a_stopped_tuning_run_resumes_to_the_uninterrupted_result(tmp_path, monkeypatch):
    spec = v1_tuning.SPECS["nussbaum"]
    flown = {"n": 0}
    original = tuning.objective

    def counting(controller, episodes):
        flown["n"] += 1
        return original(controller, episodes)

    monkeypatch.setattr(tuning, "objective", counting)

    def run(cache: str, out: str, progress: Progress = NO_PROGRESS) -> dict:
        monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / cache))
        request = TrainRequest(
            controller="nussbaum", seed=1, budget="quick", out=tmp_path / out, progress=progress
        )
        return yaml.safe_load(tuning.tune(spec, request).artifact.read_text())

    whole = run("a", "whole.yaml")
    uninterrupted = flown["n"]
    assert not any((tmp_path / "a").rglob("*.jsonl"))  # a completed run leaves no journal

    with pytest.raises(KeyboardInterrupt):
        run("b", "stopped.yaml", _StopAfter(3))
    assert not (tmp_path / "stopped.yaml").exists()
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "b"))
    journal = journal_path("nussbaum", spec.benchmark, 1, "quick")
    assert EvaluationJournal(journal).resumed == 3

    flown["n"] = 0
    resumed = run("b", "resumed.yaml")
    assert resumed["params"] == whole["params"]
    assert resumed["provenance"]["train_settled_rate"] == whole["provenance"]["train_settled_rate"]
    assert flown["n"] == uninterrupted - 3  # the three in the journal were not flown again
    assert not journal.exists()


def test_a_generation_flies_only_the_candidates_the_journal_lacks(tmp_path, monkeypatch):
    spec = v3_tuning.SPECS["pid"]
    episodes = tuning.tuning_episodes(1, 1, ("gain", "nominal"), "scftc-v3")
    xs = np.stack([spec.start(), [d.bounds()[0] for d in spec.space], [d.bounds()[1] for d in spec.space]], 1)
    reference, _ = tuning.population_losses(spec, xs, episodes)
    journal = EvaluationJournal(tmp_path / "j.jsonl")
    journal.record([xs[:, 1]], [(-5.0, 5.0)])  # a recorded loss is believed, not re-flown
    batches = []
    original = tuning.population_losses

    def recording(spec_, xs_, episodes_):
        batches.append(xs_.shape[1])
        return original(spec_, xs_, episodes_)

    monkeypatch.setattr(tuning, "population_losses", recording)
    request = TrainRequest(controller="pid", benchmark="scftc-v3", seed=0, budget="quick")
    budget = tuning.tuning_of("scftc-v3").budgets["quick"]
    evaluations = tuning.Evaluations(spec, budget, episodes, journal, request, expected=3)
    losses = evaluations.generation(xs)
    assert batches == [2]
    np.testing.assert_array_equal(losses, [reference[0], -5.0, reference[2]])
    recorded = EvaluationJournal(tmp_path / "j.jsonl").get(xs[:, 2])
    assert recorded is not None and recorded[0] == reference[2]
