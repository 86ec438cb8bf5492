"""The submitter's development loop: score your own file on the train split, evaluate a
``train --out`` result, compare two controllers pair by pair, log every episode."""

from __future__ import annotations

import csv
import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binomtest
from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.statistics import paired_by_fault
from scftc_cli.versions.v1 import VERSION

PARAMS_DIR = VERSION.params_dir

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "submissions" / "example_pd_plus" / "pd_plus.py"
SMALL = ("--n-faults", "3", "--n-seeds", "2")


def _json(*args: str) -> dict:
    result = runner.invoke(app, [*args, "--format", "json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_your_own_file_scores_on_the_train_split_with_a_notice():
    result = runner.invoke(
        app,
        [
            "eval",
            "--controller-file",
            str(EXAMPLE),
            "--split",
            "train",
            "--class",
            "gain",
            *SMALL,
            "--format",
            "json",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "pd_plus.py runs in this process, unisolated" in result.stderr
    doc = json.loads(result.stdout)
    assert doc["controller"] == "pd_plus" and doc["cells"][0]["split"] == "train"
    assert doc["provenance"]["controller_file_sha256"] == hashlib.sha256(EXAMPLE.read_bytes()).hexdigest()
    assert doc["cells"][0]["settled"]["k"] > 0  # it flies: the example identifies and settles


def test_a_broken_file_fails_in_one_line_naming_the_line(tmp_path: Path):
    bad = tmp_path / "bad_one.py"
    bad.write_text(
        EXAMPLE.read_text()
        .replace('"name": "pd_plus"', '"name": "bad_one"')
        .replace(
            "    def act(self, obs",
            "    def act(self, obs):\n        raise ValueError('boom')\n\n    def _unused(self, obs",
            1,
        )
    )
    result = runner.invoke(app, ["eval", "--controller-file", str(bad), "--class", "sign", *SMALL])
    assert result.exit_code == 1
    (line,) = [ln for ln in result.stderr.splitlines() if ln.startswith("error")]
    assert "act() raised ValueError: boom (bad_one.py line" in line


def test_exactly_one_of_controller_and_file():
    for args in ([], ["--controller", "pd", "--controller-file", str(EXAMPLE)]):
        result = runner.invoke(app, ["eval", *args, *SMALL])
        assert (
            result.exit_code == 2
            and "exactly one of --controller NAME and --controller-file" in result.stderr
        )


@pytest.mark.slow
def test_train_writes_aside_and_eval_takes_it_with_params(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.chdir(tmp_path)
    committed = (PARAMS_DIR / "nussbaum.yaml").read_bytes()
    result = runner.invoke(app, ["train", "--controller", "nussbaum", "--budget", "quick"])
    assert result.exit_code == 0, result.output
    written = tmp_path / "results" / "train" / "nussbaum.yaml"
    assert written.is_file() and "scftc eval --controller nussbaum --params" in result.stderr
    assert (PARAMS_DIR / "nussbaum.yaml").read_bytes() == committed  # never overwritten without --in-place
    doc = _json(
        "eval",
        "--controller",
        "nussbaum",
        "--params",
        str(written),
        "--split",
        "train",
        "--class",
        "sign",
        *SMALL,
    )
    assert doc["controller"] == "nussbaum (nussbaum.yaml)"
    assert list(doc["provenance"]["artifacts"].values()) == [hashlib.sha256(written.read_bytes()).hexdigest()]


def test_train_refuses_an_out_path_that_would_lose_the_weights(tmp_path: Path):
    """Weights written to ``x.yaml`` would be overwritten by their own provenance (``x.yaml``)."""
    out = tmp_path / "seed1.yaml"
    result = runner.invoke(app, ["train", "--controller", "rma_dob", "--budget", "quick", "--out", str(out)])
    assert result.exit_code == 2 and "--out must end in .npz" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not out.exists()


def test_params_of_another_controller_are_refused(tmp_path: Path):
    result = runner.invoke(
        app, ["eval", "--controller", "pid", "--params", str(PARAMS_DIR / "nussbaum.yaml"), *SMALL]
    )
    assert result.exit_code == 2 and "holds parameters of `nussbaum`, not `pid`" in result.stderr
    result = runner.invoke(
        app, ["eval", "--controller", "pd", "--params", str(PARAMS_DIR / "nussbaum.yaml"), *SMALL]
    )
    assert result.exit_code == 2 and "`pd` has no tuned parameters" in result.stderr


def test_compare_reports_discordant_pairs_and_the_exact_p_value():
    doc = _json("compare", "rls_dob", "rma_dob", "--class", "gain_bias")
    (cell,) = doc["cells"]
    assert (cell["cell"], cell["n"]) == ("gain_bias", 500)
    b, c = cell["a_only"], cell["b_only"]
    assert cell["a_settled"] - cell["b_settled"] == b - c
    assert cell["p_value"] == pytest.approx(binomtest(b, b + c, 0.5).pvalue, abs=1e-12)
    assert b + c > 0  # not a vacuous comparison
    # the by-fault test is the sign-flip test on the per-fault counts `scftc eval` prints
    a_counts, b_counts = (
        np.array(
            _json("eval", "--controller", name, "--class", "gain_bias")["cells"][0]["settled"]["by_fault"]
        )
        for name in ("rls_dob", "rma_dob")
    )
    assert cell["faults"] == a_counts.size == 50
    assert (cell["a_ahead_faults"], cell["b_ahead_faults"]) == (
        int(np.sum(a_counts > b_counts)),
        int(np.sum(b_counts > a_counts)),
    )
    assert cell["p_value_by_fault"] == paired_by_fault(a_counts, b_counts, 10) == cell["p_holm_by_fault"]
    assert "McNemar" in doc["test"] and "sign-flip" in doc["test"]


def test_compare_takes_a_file_and_holm_adjusts_across_cells():
    doc = _json("compare", str(EXAMPLE), "pd", "--class", "all", *SMALL)
    cells = doc["cells"]
    assert [c["cell"] for c in cells] == ["sign", "gain", "gain_bias", "loss"]
    raw = sorted(c["p_value"] for c in cells)
    holm = sorted(c["p_holm"] for c in cells)
    assert holm[0] == pytest.approx(min(1.0, 4 * raw[0]))
    assert all(h >= r for h, r in zip(holm, raw, strict=True))
    raw = sorted(c["p_value_by_fault"] for c in cells)
    holm = sorted(c["p_holm_by_fault"] for c in cells)
    assert holm[0] == pytest.approx(min(1.0, 4 * raw[0]))
    assert all(h >= r for h, r in zip(holm, raw, strict=True))


@pytest.mark.parametrize("suffix", [".jsonl", ".csv"])
def test_episode_log_has_one_row_per_episode(tmp_path: Path, suffix: str):
    path = tmp_path / f"episodes{suffix}"
    args = ["eval", "--controller", "bias_oracle", "--class", "all", *SMALL, "--log-episodes", str(path)]
    assert runner.invoke(app, args).exit_code == 0
    if suffix == ".jsonl":
        rows = [json.loads(line) for line in path.read_text().splitlines()]
    else:
        rows = list(csv.DictReader(path.open()))
        for r in rows:
            r["fault.gain"] = json.loads(r["fault.gain"])
            r["settled"] = r["settled"] == "True"
    assert len(rows) == 4 * 6
    row = rows[0]
    assert {
        "class",
        "fault_index",
        "seed_index",
        "fault.gain",
        "fault.bias",
        "fault.inertia_scale",
        "sigma0",
    } <= set(row)
    assert {"settled", "operational", "touch_once", "final_error_deg", "settling_time_s"} <= set(row)
    assert len(row["fault.gain"]) == 3
    settled = [r for r in rows if r["settled"]]
    assert settled and all(r["settling_time_s"] not in (None, "") for r in settled)
