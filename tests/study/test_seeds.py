"""The training-seed table: every seed's weights are found beside the committed ones, flown on the
held-out cells, and summarised by seed, mean and range."""

from __future__ import annotations

import shutil
from pathlib import Path
from types import SimpleNamespace

from scftc_cli.evaluate import Cell
from scftc_cli.registry import controller_spec
from scftc_cli.spec import V1
from scftc_cli.study.seeds import seed_artifacts, seed_spread, seeds_markdown


def test_seeds_beside_the_committed_weights_are_flown_and_summarised(tmp_path: Path):
    entry = controller_spec("rma_student")
    (committed,) = entry.artifact_paths()
    for suffix in (".npz", ".yaml"):
        shutil.copy(committed.with_suffix(suffix), tmp_path / f"rma_student{suffix}")
    folder = tmp_path / "seeds" / "rma_student"
    folder.mkdir(parents=True)
    shutil.copy(committed, folder / "seed3.npz")  # the same weights under another seed's name
    moved = SimpleNamespace(  # the same controller, its committed weights copied to tmp_path
        name=entry.name,
        family=entry.family,
        artifacts=entry.artifacts,
        artifact_paths=lambda: [tmp_path / "rma_student.npz"],
        load=entry.load,
        make=entry.make,
    )
    assert sorted(seed_artifacts(moved)) == [0, 3]
    assert seed_artifacts(controller_spec("pd")) == {}  # not learned: no seeds
    spread = seed_spread(moved, V1, [Cell("test", "sign"), Cell("test", "gain_bias")])
    assert spread is not None and spread.rates[0] == spread.rates[3]  # same weights, same episodes
    assert spread.rates[0] == [1.0, 0.0]  # rma_student's held-out sign and gain_bias, as the battery has
    text = seeds_markdown(V1, [spread])
    assert "| 0 (committed) | 100.0 | 0.0 |" in text and "| range | 100.0-100.0 | 0.0-0.0 |" in text
