"""The leaderboard: validation on read, atomic locked writes, ranking, rendering, verify, schemas,
the committed board, and the private draw that catches a submission that looks its faults up.

Boards here are tiny (1-4 faults x 1-2 seeds per cell); the full-size verify is CI's
``scftc leaderboard verify``.
"""

from __future__ import annotations

import csv
import io
import json
import multiprocessing
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import scftc_cli.board.ops as lb
import scftc_cli.board.store as store
from scftc_cli.board.draws import flagged_cells, key_id, load_secret, private_salt
from scftc_cli.board.models import Entry, Leaderboard, schema_documents
from scftc_cli.board.ops import Scoring, builtin_entry
from scftc_cli.board.ranking import mean_settled, rank_board
from scftc_cli.board.render import board_csv, board_json, board_markdown
from scftc_cli.board.store import read_board as _read_board
from scftc_cli.board.store import update_board as _update_board
from scftc_cli.commands.app import app
from scftc_cli.errors import LeaderboardError
from scftc_cli.evaluate import Cell, board_cells, evaluate_cell
from scftc_cli.records import CellResult, FinalError
from scftc_cli.registry import make_controller, registry
from scftc_cli.scoring import gate_stat
from scftc_cli.spec import V1

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "submissions" / "example_pd_plus" / "pd_plus.py"
COMMITTED = ROOT / "leaderboard" / "scftc-v1.json"
TINY = Scoring(V1, n_faults=1, n_seeds=1)
RANKED = V1.ranked_classes


def read_board(path: Path) -> Leaderboard:
    return _read_board(path, V1.version)


def update_board(path: Path, change) -> Leaderboard:
    return _update_board(path, V1.version, change)


SMALL_BATTERY = ("pd", "teacher")


@pytest.fixture(scope="module")
def tiny_entries() -> dict[str, Entry]:
    return {name: builtin_entry(name, TINY) for name in SMALL_BATTERY}


@pytest.fixture
def small_registry(monkeypatch: pytest.MonkeyPatch) -> None:
    """Pretend the battery is just ``pd`` and ``teacher`` so a tiny board is complete."""
    full = registry()
    small = {name: full[name] for name in SMALL_BATTERY}
    monkeypatch.setattr(lb, "registry", lambda _benchmark=None: dict(small))


@pytest.fixture
def board(tmp_path: Path, tiny_entries: dict[str, Entry]) -> Path:
    path = tmp_path / "leaderboard" / "scftc-v1.json"
    update_board(path, lambda b: b.model_copy(update={"entries": list(tiny_entries.values())}))
    return path


# ------------------------------------------------------------------------------ hand-made entries
def _cell(fault_class: str, sensor: str | None, k: int, n: int) -> CellResult:
    passed = np.arange(n) < k
    stat = gate_stat(passed)
    return CellResult(
        split="test",
        fault_class=fault_class,
        sensor=sensor,
        n=n,
        settled=stat,
        operational=stat,
        touch_once=stat,
        final_error_deg=FinalError(median=1.0, mean=2.0),
    )


def _entry(name: str, ks: dict[str, int], n: int = 10, privileged: bool = False, private=None) -> Entry:
    """An entry whose settled count on class ``c`` is ``ks.get(c, 0)`` (``n`` episodes per cell)."""

    def cells(counts: dict[str, int]) -> list[CellResult]:
        return [_cell(c.fault_class, c.sensor, counts.get(c.label, 0), n) for c in board_cells(V1)]

    return Entry(
        name=name,
        kind="builtin",
        privileged=privileged,
        summary="hand-made",
        benchmark_version="scftc-v1",
        package_version="0",
        created_utc="2025-01-01T00:00:00Z",
        n_faults=n,
        n_seeds=1,
        public=cells(ks),
        private=None if private is None else cells(private),
        private_key_id=None if private is None else "0" * 12,
    )


# ---------------------------------------------------------------------------------------- ranking
def test_ranking_by_mean_settled_then_lower_bound_with_oracles_apart():
    board = Leaderboard(
        entries=[
            _entry("low", {"sign": 2, "gain": 2, "gain_bias": 2}),
            _entry("high", {"sign": 10, "gain": 10, "gain_bias": 1}),
            _entry("oracle", {"sign": 10, "gain": 10, "gain_bias": 10}, privileged=True),
            # Same mean as `low` (6/30), concentrated on one class: a higher mean Wilson lower bound.
            _entry("lopsided", {"sign": 6, "loss": 10}),
        ]
    )
    ranking = rank_board(board)
    assert [r.entry.name for r in ranking.deployable] == ["high", "lopsided", "low"]
    assert [r.rank for r in ranking.deployable] == [1, 2, 3]
    assert ranking.deployable[0].mean_settled == pytest.approx(21 / 30)
    assert ranking.deployable[1].mean_settled == pytest.approx(ranking.deployable[2].mean_settled)  # a tie...
    assert ranking.deployable[1].mean_ci_low > ranking.deployable[2].mean_ci_low  # ...broken by the bound
    assert [r.entry.name for r in ranking.upper_bounds] == ["oracle"]
    assert ranking.draw == "public"


def test_flag_when_public_beats_private_beyond_the_intervals():
    cheat = _entry("cheat", {"gain_bias": 10, "sign": 6}, private={"sign": 5})
    assert flagged_cells(cheat) == ["gain_bias"]  # 10/10 vs 0/10 is flagged; 6/10 vs 5/10 is not
    assert flagged_cells(_entry("honest", {"sign": 9}, private={"sign": 8})) == []
    assert flagged_cells(_entry("public_only", {"sign": 9})) == []


def test_renderings_say_how_they_rank_and_show_intervals():
    board = Leaderboard(
        version=3,
        entries=[
            _entry("alpha", {"sign": 5, "gain": 5}),
            _entry("oracle", {"sign": 10}, privileged=True),
            _entry("cheat", {"gain_bias": 10}, private={}),
        ],
    )
    md = board_markdown(board)
    assert "mean settled rate over the controllable classes (sign, gain, gain_bias)" in md
    assert "Wilson 95 % lower bound" in md and "Upper bounds" in md
    assert "| 1 | `cheat` |" in md and "| 2 | `alpha` |" in md
    assert "50.0 [23.7, 76.3]" in md  # 5/10 with its Wilson interval
    assert "public draw only" in md and "public > private on gain_bias" in md
    doc = json.loads(board_json(board))
    assert doc["version"] == 3 and doc["standings"]["draw"] == "public"
    assert [r["name"] for r in doc["standings"]["deployable"]] == ["cheat", "alpha"]
    assert [r["name"] for r in doc["standings"]["upper_bounds"]] == ["oracle"]
    rows = list(csv.DictReader(io.StringIO(board_csv(board))))
    assert len(rows) == 4 * 10  # three public draws + one private, ten cells each
    assert {r["flagged"] for r in rows if r["name"] == "cheat" and r["cell"] == "gain_bias"} == {"True"}


# ------------------------------------------------------------------------------- reads and writes
def test_validation_catches_a_rate_that_is_not_k_over_n(board: Path):
    doc = json.loads(board.read_text())
    doc["entries"][0]["public"][1]["settled"]["k"] += 1
    board.write_text(json.dumps(doc))
    with pytest.raises(LeaderboardError, match="edited by hand"):
        read_board(board)


def test_corrupt_board_is_refused_and_never_overwritten(board: Path):
    board.write_bytes(b'{"format": "scftc-leaderboard/1", "entries": [')
    before = board.read_bytes()
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(board)])
    assert result.exit_code == 1
    assert "not valid JSON" in result.stderr and "git checkout" in result.stderr
    result = runner.invoke(
        app, ["submit", str(EXAMPLE), "--leaderboard", str(board), "--n-faults", "1", "--n-seeds", "1"]
    )
    assert result.exit_code == 1 and "not valid JSON" in result.stderr
    with pytest.raises(LeaderboardError):
        update_board(board, lambda b: b)
    assert board.read_bytes() == before


def test_a_crash_mid_write_loses_nothing(board: Path, monkeypatch: pytest.MonkeyPatch):
    before = board.read_bytes()

    def crash(*_args: object) -> None:
        raise OSError("disk on fire")

    monkeypatch.setattr(store.os, "replace", crash)
    with pytest.raises(OSError, match="disk on fire"):
        update_board(board, lambda b: b)
    assert board.read_bytes() == before
    assert sorted(p.name for p in board.parent.iterdir()) == ["scftc-v1.json", "scftc-v1.json.lock"]


def _append_copies(path: str, entry_json: str, names: list[str]) -> None:
    entry = Entry.model_validate_json(entry_json)
    for name in names:
        update_board(
            Path(path),
            lambda b, n=name: b.model_copy(
                update={"entries": [*b.entries, entry.model_copy(update={"name": n})]}
            ),
        )


def test_concurrent_writers_all_land(board: Path, tiny_entries: dict[str, Entry]):
    start = read_board(board).version
    entry_json = tiny_entries["pd"].model_dump_json(by_alias=True)
    ctx = multiprocessing.get_context("fork")
    procs = [
        ctx.Process(target=_append_copies, args=(str(board), entry_json, [f"w{i}_{j}" for j in range(5)]))
        for i in range(3)
    ]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    final = read_board(board)
    assert final.version == start + 15
    assert {f"w{i}_{j}" for i in range(3) for j in range(5)} <= {e.name for e in final.entries}


def test_two_submits_started_together_both_land(board: Path, tmp_path: Path):
    start = read_board(board).version
    files = []
    for name in ("racer_a", "racer_b"):
        path = tmp_path / f"{name}.py"
        path.write_text(EXAMPLE.read_text().replace('"name": "pd_plus"', f'"name": "{name}"'))
        files.append(path)
    scftc = [sys.executable, "-m", "scftc_cli"]
    env = {k: v for k, v in os.environ.items() if not k.startswith("SCFTC_SECRET")}
    procs = [
        subprocess.Popen(
            [*scftc, "submit", str(f), "--leaderboard", str(board), "--n-faults", "1", "--n-seeds", "1"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
        )
        for f in files
    ]
    for p in procs:
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err.decode()
    final = read_board(board)
    assert final.version == start + 2
    assert {"racer_a", "racer_b"} <= {e.name for e in final.entries}


# ------------------------------------------------------------------------------------------ verify
def test_verify_passes_then_fails_after_a_hand_edit(board: Path, small_registry: None):
    submissions = board.parent.parent / "submissions" / "example"
    submissions.mkdir(parents=True)
    shutil.copy(EXAMPLE, submissions / "pd_plus.py")
    submit = ["submit", str(submissions / "pd_plus.py"), "--leaderboard", str(board)]
    assert runner.invoke(app, [*submit, "--n-faults", "1", "--n-seeds", "1"]).exit_code == 0

    result = runner.invoke(app, ["leaderboard", "verify", "--leaderboard", str(board)])
    assert result.exit_code == 0, result.output
    assert "[3/3] pd_plus: ok" in result.stderr and "verified 3 entries" in result.stdout

    before = board.read_text()
    doc = json.loads(before)
    doc["entries"][2]["public"][2]["final_error_deg"]["median"] += 0.5  # one number, by hand
    board.write_text(json.dumps(doc, indent=1))
    result = runner.invoke(app, ["leaderboard", "verify", "--leaderboard", str(board)])
    assert result.exit_code == 1
    assert "pd_plus: public gain_bias final error median" in result.stderr
    assert "does not match the code for pd_plus" in result.stderr

    doc = json.loads(before)
    doc["entries"][0]["public"][0]["touch_once"]["k"] = 1 - doc["entries"][0]["public"][0]["touch_once"]["k"]
    board.write_text(json.dumps(doc, indent=1))
    result = runner.invoke(app, ["leaderboard", "verify", "--leaderboard", str(board)])
    assert result.exit_code == 1 and "edited by hand" in result.stderr


def test_verify_names_a_missing_submission_file_and_a_missing_builtin(board: Path, tmp_path: Path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shutil.copy(EXAMPLE, elsewhere / "pd_plus.py")
    runner.invoke(
        app,
        [
            "submit",
            str(elsewhere / "pd_plus.py"),
            "--leaderboard",
            str(board),
            "--n-faults",
            "1",
            "--n-seeds",
            "1",
        ],
    )
    shutil.rmtree(elsewhere)
    report = lb.verify(board, TINY)
    assert any(p.startswith("pd_plus: file with sha256") for p in report.problems)
    assert any(p.startswith("bias_oracle: registered controller missing") for p in report.problems)


# --------------------------------------------------------------------------- public vs private draw
CHEAT = """
import numpy as np

from scftc_cli.sim.v1.faults import draw_episodes

SUBMISSION = {
    "name": "lookup_cheat",
    "version": "1",
    "authors": ["Mallory"],
    "description": "regenerates the public episodes from the open code and looks the fault up",
    "entry": "Cheat",
    "license": "MIT",
}


class Cheat:
    def reset(self, n, context):
        self.n, self.ctx, self.fault = n, context, None
        self.first = True

    def _lookup(self, omega0):
        for n_faults in [d for d in range(1, self.n + 1) if self.n % d == 0]:
            for cls in ("sign", "gain", "gain_bias", "loss"):
                ep = draw_episodes("test", cls, None, n_faults, self.n // n_faults)
                if np.array_equal(ep.omega0_rad_s, omega0):  # the gyro reads the true initial rate
                    return ep.fault.theta, ep.fault.beta
        return None

    def act(self, obs):
        if self.first:
            self.fault, self.first = self._lookup(obs[:, 3:]), False
        i0, tau = self.ctx.inertia_nominal_kgm2, self.ctx.tau_max_nm
        u0 = -i0 * (0.04 * obs[:, :3] + 0.14 * obs[:, 3:]) / tau
        if self.fault is None:  # a private draw: nothing to look up, plain PD
            return np.clip(u0, -1.0, 1.0)
        theta, beta = self.fault
        theta = np.where(theta >= 0, 1.0, -1.0) * np.maximum(np.abs(theta), 0.05)
        return np.clip((u0 - beta) / theta, -1.0, 1.0)
"""


def test_private_draw_exposes_a_submission_that_looks_up_public_episodes(
    board: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.setenv("SCFTC_SECRET", "test-secret-not-for-production")
    cheat = tmp_path / "lookup_cheat.py"
    cheat.write_text(CHEAT)
    size = ["--n-faults", "4", "--n-seeds", "2"]
    for path in (cheat, EXAMPLE):
        result = runner.invoke(app, ["submit", str(path), "--leaderboard", str(board), *size])
        assert result.exit_code == 0, result.output
    entries = {e.name: e for e in read_board(board).entries}
    cheat_entry, honest = entries["lookup_cheat"], entries["pd_plus"]
    assert cheat_entry.private is not None and honest.private is not None
    assert cheat_entry.private_key_id == key_id(b"test-secret-not-for-production")
    public_mean, _ = mean_settled(cheat_entry.public, RANKED)
    private_mean, _ = mean_settled(cheat_entry.private, RANKED)
    honest_private, _ = mean_settled(honest.private, RANKED)
    assert public_mean >= 0.9  # it "knows" every fault of the public draw...
    assert "gain_bias" in flagged_cells(cheat_entry)  # ...which the private draw exposes
    assert private_mean <= honest_private  # and it is no better than an honest controller there
    assert flagged_cells(honest) == []
    md = runner.invoke(app, ["leaderboard", "--leaderboard", str(board)]).stdout
    assert "## Flagged" in md and "`lookup_cheat`" in md.split("## Flagged")[1]


def test_secret_from_a_key_file(tmp_path: Path):
    key = tmp_path / "key"
    key.write_text("s3cret\n")
    assert load_secret({"SCFTC_SECRET_FILE": str(key)}) == (b"s3cret", key)
    assert load_secret({}) == (None, None)
    with pytest.raises(LeaderboardError, match="cannot read"):
        load_secret({"SCFTC_SECRET_FILE": str(tmp_path / "missing")})
    assert private_salt(b"a", "scftc-v1") != private_salt(b"b", "scftc-v1")


# ----------------------------------------------------------------------------- schemas and the repo
def test_schemas_are_up_to_date():
    for name, doc in schema_documents().items():
        path = ROOT / "schemas" / name
        assert path.exists(), f"missing {path}; run `scftc schemas --out schemas`"
        assert json.loads(path.read_text()) == doc, (
            f"{path} is out of date; run `scftc schemas --out schemas`"
        )
    assert runner.invoke(app, ["schemas", "--out", str(ROOT / "schemas"), "--check"]).exit_code == 0


def test_schemas_check_fails_when_stale(tmp_path: Path):
    result = runner.invoke(app, ["schemas", "--out", str(tmp_path), "--check"])
    assert result.exit_code == 1 and "scftc schemas" in result.stderr


def test_committed_board_validates_against_its_schema():
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads((ROOT / "schemas" / "leaderboard.schema.json").read_text())
    jsonschema.validate(json.loads(COMMITTED.read_text()), schema)


def test_committed_board_holds_the_whole_battery_at_full_size():
    board = read_board(COMMITTED)
    entries = {e.name: e for e in board.entries if e.kind == "builtin"}
    battery = registry()
    assert set(entries) == set(battery), "run `scftc leaderboard rebuild`"
    for name, entry in entries.items():
        assert entry.privileged == battery[name].privileged
        assert (entry.n_faults, entry.n_seeds) == (50, 10)


@pytest.mark.parametrize("name", ["pd", "teacher", "bias_oracle"])
def test_committed_board_matches_a_rerun_of_one_cell(name: str):
    """A cheap spot check; `scftc leaderboard verify` re-runs everything."""
    entry = read_board(COMMITTED).entry(name)
    cell = Cell("test", "gain_bias")
    rerun = evaluate_cell(lambda _c: make_controller(name), V1, cell).result
    on_board = next(c for c in entry.public if c.key == ("test", "gain_bias", None))
    assert lb.compare_cells([on_board], [rerun]) == []


def test_leaderboard_command_shows_the_committed_board():
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(COMMITTED), "--format", "markdown"])
    assert result.exit_code == 0
    assert "## Deployable controllers" in result.stdout and "`bias_oracle`" in result.stdout
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(COMMITTED), "--format", "json"])
    assert json.loads(result.stdout)["standings"]["deployable"][0]["rank"] == 1
