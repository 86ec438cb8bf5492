"""``scftc eval`` through the CLI: the JSON contract, exit codes, and the oracle calibration."""

from __future__ import annotations

import json
import os

import pytest
from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.statistics import PROFILE_TAUS_DEG, design_effect, interval_by_fault

runner = CliRunner()


def _eval_json(*args: str) -> dict:
    result = runner.invoke(app, ["eval", *args, "--format", "json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_json_output_carries_its_provenance():
    doc = _eval_json("--controller", "rls_dob", "--class", "sign", "--n-faults", "1", "--n-seeds", "1")
    prov = doc["provenance"]
    assert prov["package_version"] and prov["python"].count(".") == 2
    assert {"numpy", "numba", "scipy"} <= set(prov["libraries"])
    (path, digest), *_ = prov["artifacts"].items()
    assert path == "scftc_cli/params/rls_dob.yaml" and len(digest) == 64
    assert prov["git_commit"] is None or len(prov["git_commit"]) == 40


def test_json_output_has_the_contract_fields():
    doc = _eval_json("--controller", "pd", "--class", "gain_bias", "--n-faults", "2", "--n-seeds", "2")
    assert set(doc) == {"benchmark_version", "controller", "privileged", "backend", "cells", "provenance"}
    assert (doc["benchmark_version"], doc["controller"], doc["privileged"], doc["backend"]) == (
        "scftc-v1",
        "pd",
        False,
        "numpy",
    )
    (cell,) = doc["cells"]
    assert set(cell) == {
        "split",
        "class",
        "sensor",
        "n",
        "settled",
        "operational",
        "touch_once",
        "final_error_deg",
        "settled_profile",
    }
    assert (cell["split"], cell["class"], cell["sensor"], cell["n"]) == ("test", "gain_bias", None, 4)
    for gate in ("settled", "operational", "touch_once"):
        assert set(cell[gate]) == {
            "k",
            "rate",
            "ci_low",
            "ci_high",
            "by_fault",
            "interval_by_fault",
            "design_effect",
        }
        assert cell[gate]["ci_low"] <= cell[gate]["rate"] <= cell[gate]["ci_high"]
        by_fault = cell[gate]["by_fault"]
        assert len(by_fault) == 2 and sum(by_fault) == cell[gate]["k"]
        low, high = cell[gate]["interval_by_fault"]
        assert low <= cell[gate]["rate"] <= high
        # anyone can recompute the by-fault numbers from the per-fault counts in the document
        assert (low, high) == interval_by_fault(by_fault, cell["n"] // len(by_fault))
        assert cell[gate]["design_effect"] == design_effect(by_fault, cell["n"] // len(by_fault))
    assert set(cell["final_error_deg"]) == {"median", "mean", "profile"}
    profile = cell["final_error_deg"]["profile"]  # episodes within each threshold: non-decreasing
    assert len(profile) == len(PROFILE_TAUS_DEG) and profile == sorted(profile) and profile[-1] == cell["n"]


def test_sensor_all_gives_six_cells_on_sign_faults():
    doc = _eval_json("--controller", "teacher", "--sensor", "all", "--n-faults", "1", "--n-seeds", "1")
    assert [c["sensor"] for c in doc["cells"]] == [
        "bias_0.1",
        "bias_0.2",
        "bias_0.3",
        "bias_0.5",
        "dropout",
        "stuck",
    ]
    assert {c["class"] for c in doc["cells"]} == {"sign"} and doc["privileged"] is True


@pytest.mark.parametrize(
    ("args", "listed"),
    [
        (["--controller", "rma_dop"], "teacher"),
        (["--controller", "pd", "--class", "sig"], "gain_bias"),
        (["--controller", "pd", "--sensor", "bias_0.4"], "dropout"),
        (["--controller", "pd", "--split", "validation"], "train"),
        (["--controller", "pd", "--class", "gain", "--sensor", "dropout"], "sign"),
    ],
)
def test_unknown_names_exit_2_and_list_the_valid_ones(args, listed):
    result = runner.invoke(app, ["eval", *args])
    assert result.exit_code == 2
    assert listed in result.stderr and len(result.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_oracles_and_pd_reproduce_the_spec_calibration():
    """The calibration point: teacher ~100 % on sign/gain and 0 % on gain_bias; bias oracle ~96 %."""
    teacher = {c["class"]: c["settled"]["rate"] for c in _eval_json("--controller", "teacher")["cells"]}
    assert teacher["sign"] >= 0.99 and teacher["gain"] >= 0.99 and teacher["gain_bias"] == 0.0
    oracle = _eval_json("--controller", "bias_oracle", "--class", "gain_bias")["cells"][0]
    assert oracle["n"] == 500 and 0.90 <= oracle["settled"]["rate"] <= 1.0
    pd = _eval_json("--controller", "pd", "--class", "sign")["cells"][0]
    assert pd["settled"]["rate"] == 0.0


def test_without_a_terminal_long_work_logs_plain_progress_lines_and_short_work_none(monkeypatch, capsys):
    from scftc_cli.commands import common

    with common.progress_bar("short job", 10) as progress:  # pytest's stderr is not a terminal
        progress.advance(5)
    assert capsys.readouterr().err == ""

    monkeypatch.setattr(common, "LOG_QUIET_S", 0.0)
    monkeypatch.setattr(common, "LOG_EVERY_S", 3600.0)
    with common.progress_bar("long job", 10) as progress:
        progress.advance(4)
        progress.advance(1)  # within LOG_EVERY_S of the first line: not written
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].endswith("long job: 40%"), lines


@pytest.mark.parametrize(
    "args",
    [
        ["list"],
        ["list", "--benchmark", "scftc-v2"],
        ["eval", "--controller", "pd", "--class", "all", "--n-faults", "2", "--n-seeds", "1"],
        ["compare", "pd", "teacher", "--class", "all", "--n-faults", "2", "--n-seeds", "1"],
    ],
)
def test_terminal_output_fits_an_80_column_terminal(args: list[str]):
    import subprocess
    import sys

    env = {**os.environ, "COLUMNS": "80"}
    out = subprocess.run(
        [sys.executable, "-m", "scftc_cli", *args], capture_output=True, text=True, env=env, timeout=300
    )
    assert out.returncode == 0, out.stderr
    widest = max(len(line) for line in out.stdout.splitlines())
    assert widest <= 80, (widest, out.stdout)
