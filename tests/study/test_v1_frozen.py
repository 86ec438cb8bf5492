"""``scftc-v1``'s numbers never change: the full study (every built-in on every held-out class, the
sensor table) gives exactly the k of every gate frozen in ``tests/data/scftc-v1-frozen-k.json``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from scftc_cli.spec import V1
from scftc_cli.study.run import run_study

FROZEN = json.loads((Path(__file__).resolve().parents[1] / "data" / "scftc-v1-frozen-k.json").read_text())


@pytest.mark.slow
def test_the_full_study_gives_the_frozen_numbers() -> None:
    study = run_study(V1)
    compared = 0
    for name, runs in study.runs.items():
        for run in runs:
            frozen = FROZEN["cells"][name][run.cell.label]
            got = {gate: getattr(run.result, gate).k for gate in frozen}
            assert run.result.n == FROZEN["n"]
            assert got == frozen, (name, run.cell.label)
            compared += 1
    assert compared == len(study.battery.results) * len(V1.fault_classes) + 2 * len(V1.sensor_faults)
