"""The leaderboard: full-size entries on a public and a sealed draw, validation on read, atomic
locked writes that survive a crash, ranking in tie groups, rendering, history and removal.

Entries here are made by hand (synthetic counts at the full cell size) unless the test is about
scoring; `tests/board/test_verify.py` re-flies real ones.
"""

from __future__ import annotations

import csv
import io
import json
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import fisher_exact
from typer.testing import CliRunner

import scftc_cli.board.store as store
from scftc_cli.board.models import Entry, Leaderboard, Round, ranking_rule
from scftc_cli.board.ops import remove
from scftc_cli.board.ranking import pooled_settled, rank_board
from scftc_cli.board.render import board_csv, board_json, board_markdown
from scftc_cli.board.rounds import commitment
from scftc_cli.commands.app import app
from scftc_cli.errors import LeaderboardError, UnknownNameError
from scftc_cli.evaluate import board_cells
from scftc_cli.records import CellResult, FinalError
from scftc_cli.scoring import gate_stat, wilson_interval
from scftc_cli.statistics import profile_counts, two_sample_by_fault
from scftc_cli.versions.v1.spec import V1

runner = CliRunner()
N = V1.episodes_per_cell  # 500: boards hold full-size entries only
SALT = "ab" * 32
SECRET = "5e" * 32


def round_one() -> Round:
    """A sealed round 1 (committed at board version 1, sealed at version 3): hand-made entries
    belong to it (added at version 2)."""
    return Round(
        number=1,
        commitment=commitment(bytes.fromhex(SECRET)),
        opened_board_version=1,
        opened_utc="2026-01-01T00:00:00Z",
        status="sealed",
        secret=SECRET,
        closed_board_version=3,
    )


def board_of(entries: list[Entry], **fields: object) -> Leaderboard:
    """A board whose round 1 holds ``entries`` (sealed)."""
    return Leaderboard(rounds=[round_one()], entries=entries, **fields)


def read_board(path: Path) -> Leaderboard:
    return store.read_board(path, V1.version)


def update_board(path: Path, change) -> Leaderboard:
    return store.update_board(path, V1.version, change)


def cell(fault_class: str, sensor: str | None, k: int, n: int = N) -> CellResult:
    """A full-size cell with ``k`` settled episodes spread over its faults as evenly as they go
    (episode ``i`` belongs to fault ``i % n_faults``), every gate alike."""
    passed = np.arange(n) < k
    stat = gate_stat(passed, fault_index=np.arange(n) % V1.n_faults)
    final = np.where(passed, 0.1, 10.0)
    return CellResult(
        split="test",
        fault_class=fault_class,
        sensor=sensor,
        n=n,
        settled=stat,
        operational=stat,
        touch_once=stat,
        final_error_deg=FinalError(
            median=float(np.median(final)), mean=float(np.mean(final)), profile=profile_counts(final).tolist()
        ),
    )


def entry(
    name: str, sealed: dict[str, int], public: dict[str, int] | None = None, privileged: bool = False
) -> Entry:
    """A full-size entry whose settled count on cell ``c`` is ``counts.get(c, 0)``."""

    def cells(counts: dict[str, int]) -> list[CellResult]:
        return [cell(c.fault_class, c.sensor, counts.get(c.label, 0)) for c in board_cells(V1)]

    return Entry(
        name=name,
        kind="builtin",
        privileged=privileged,
        summary="hand-made",
        benchmark_version="scftc-v1",
        package_version="0",
        created_utc="2026-01-01T00:00:00Z",
        n_faults=V1.n_faults,
        n_seeds=V1.n_seeds,
        status="sealed",
        round=1,
        added_board_version=2,
        public=cells(sealed if public is None else public),
        sealed=cells(sealed),
        sealed_salt=SALT,
    )


def ks(sign: int, gain: int, gain_bias: int, **more: int) -> dict[str, int]:
    return {"sign": sign, "gain": gain, "gain_bias": gain_bias, **more}


@pytest.fixture
def board(tmp_path: Path) -> Path:
    path = tmp_path / "leaderboard" / "scftc-v1.json"
    entries = [entry("alpha", ks(500, 500, 480)), entry("beta", ks(500, 500, 470))]
    update_board(path, lambda b: b.model_copy(update={"rounds": [round_one()], "entries": entries}))
    return path


# ---------------------------------------------------------------------------------------- ranking
def test_the_ranked_quantity_is_the_pooled_sealed_count_with_its_wilson_interval():
    e = entry("xx", ks(500, 490, 300), public=ks(500, 500, 500))
    pooled = pooled_settled(e.sealed, V1.ranked_classes)
    assert (pooled.k, pooled.n) == (1290, 1500)
    rates = [c.settled.rate for c in e.sealed if c.sensor is None and c.fault_class in V1.ranked_classes]
    assert pooled.rate == pytest.approx(np.mean(rates))  # equal n per class: pooled = mean of rates
    assert pooled.interval == wilson_interval(1290, 1500)


def test_tie_groups_follow_the_by_fault_test_on_the_sealed_draw_and_oracles_stand_apart():
    board = board_of(
        entries=[
            entry("top", ks(500, 500, 490)),  # 1490 / 1500
            entry("close", ks(500, 500, 484)),  # 1484: the by-fault test does not separate it from `top`
            entry("third", ks(500, 500, 440)),  # 1440: separated from `top`
            entry("oracle", ks(500, 500, 500), privileged=True),
            entry("public_hero", ks(400, 400, 400), public=ks(500, 500, 500)),
        ]
    )

    def strata(name: str) -> list[np.ndarray]:
        e = next(x for x in board.entries if x.name == name)
        return [
            np.array(c.settled.by_fault) for c in e.sealed if c.sensor is None and c.fault_class != "loss"
        ]

    assert two_sample_by_fault(strata("top"), strata("close"), V1.n_seeds) >= 0.05
    assert two_sample_by_fault(strata("top"), strata("third"), V1.n_seeds) < 0.05
    ranking = rank_board(board)
    order = [(r.entry.name, r.rank, r.tied) for r in ranking.deployable]
    assert order == [("top", 1, True), ("close", 1, True), ("third", 3, False), ("public_hero", 4, False)]
    assert [r.entry.name for r in ranking.upper_bounds] == ["oracle"]
    assert "public_hero" not in [
        r.entry.name for r in ranking.deployable[:3]
    ]  # its public score ranks nothing
    assert "exchanging whole faults" in ranking_rule(V1.ranked_classes, N)


def test_clustered_outcomes_widen_the_by_fault_interval_and_can_merge_a_tie_group():
    """The same counts, drawn all-or-nothing per fault (what a controller that cannot handle a
    fault does): the Wilson interval is unchanged, the by-fault one is much wider, and two entries
    Fisher's test would separate are tied by fault."""

    def clustered(name: str, k: int) -> Entry:
        e = entry(name, ks(k, k, k))
        cells = []
        for c in e.sealed:
            passed = np.arange(N) < c.settled.k  # fault-major: the first faults settle all 10
            stat = gate_stat(passed, fault_index=np.arange(N) // V1.n_seeds)
            cells.append(c.model_copy(update={"settled": stat, "operational": stat, "touch_once": stat}))
        return e.model_copy(update={"sealed": cells})

    a, b = clustered("alpha", 350), clustered("beta", 300)
    spread_a = pooled_settled(entry("spread", ks(350, 350, 350)).sealed, V1.ranked_classes)
    pa, pb = pooled_settled(a.sealed, V1.ranked_classes), pooled_settled(b.sealed, V1.ranked_classes)
    assert pa.interval == spread_a.interval
    width = lambda iv: iv[1] - iv[0]  # noqa: E731
    assert width(pa.interval_by_fault) > 2 * width(pa.interval)  # clustered: much wider than Wilson
    assert width(spread_a.interval_by_fault) < 1.5 * width(spread_a.interval)  # spread: close to Wilson
    assert fisher_exact([[pa.k, pa.n - pa.k], [pb.k, pb.n - pb.k]])[1] < 0.05
    ranking = rank_board(board_of(entries=[a, b]))
    assert [(r.entry.name, r.rank, r.tied) for r in ranking.deployable] == [
        ("alpha", 1, True),
        ("beta", 1, True),
    ]


def test_public_beating_sealed_beyond_the_intervals_is_flagged():
    board = board_of(
        entries=[entry("cheat", ks(0, 0, 0), public=ks(500, 500, 500)), entry("honest", ks(450, 440, 430))]
    )
    flags = {r.entry.name: r.flagged for r in rank_board(board).deployable}
    assert flags["cheat"] == ["sign", "gain", "gain_bias", "mean"]
    assert flags["honest"] == []


def test_renderings_say_how_they_rank_and_show_both_draws():
    board = board_of(
        version=3,
        ranking="RULE TEXT",
        entries=[
            entry("alpha", ks(250, 250, 250)),
            entry("beta", ks(250, 251, 250)),
            entry("oracle", ks(500, 500, 500), privileged=True),
            entry("cheat", ks(0, 0, 0), public=ks(500, 500, 500)),
        ],
    )
    md = board_markdown(board)
    assert "**Ranking:** RULE TEXT." in md and "Upper bounds" in md
    assert "| 1= | `beta` |" in md and "| 1= | `alpha` |" in md and "| 3 | `cheat` |" in md
    assert "50.0 [45.6, 54.4]" in md  # 250/500 with its Wilson interval
    assert "public above sealed on sign, gain, gain_bias, mean" in md and "## Flagged" in md
    assert "exact two-sample test over faults" in md
    doc = json.loads(board_json(board))
    assert doc["version"] == 3
    standings = doc["standings"]["deployable"]
    assert [(r["name"], r["rank"], r["tied"]) for r in standings] == [
        ("beta", 1, True),
        ("alpha", 1, True),
        ("cheat", 3, False),
    ]
    assert standings[0]["sealed_settled"]["k"] == 751 and standings[0]["sealed_settled"]["n"] == 1500
    rows = list(csv.DictReader(io.StringIO(board_csv(board))))
    assert len(rows) == 4 * 2 * 10  # four entries, two draws, ten cells
    assert [r["name"] for r in rows[::20]] == ["beta", "alpha", "cheat", "oracle"]  # rank order, oracles last


# ------------------------------------------------------------------------------------- validation
def test_validation_catches_a_rate_that_is_not_k_over_n_and_names_the_board(board: Path):
    doc = json.loads(board.read_text())
    doc["entries"][0]["sealed"][1]["settled"]["k"] += 1
    board.write_text(json.dumps(doc))
    with pytest.raises(LeaderboardError, match=f"{board}.*edited by hand.*git checkout -- {board}"):
        read_board(board)


def test_only_full_size_entries_with_a_sealed_salt_are_accepted():
    small = entry("tiny", ks(1, 1, 1)).model_dump(by_alias=True)
    small["n_faults"], small["n_seeds"] = 1, 1
    with pytest.raises(ValueError, match="only full-size runs are ranked"):
        Entry.model_validate(small)
    unsalted = entry("xx", ks(1, 1, 1)).model_dump(by_alias=True)
    unsalted["sealed_salt"] = "00"
    with pytest.raises(ValueError, match="sealed_salt"):
        Entry.model_validate(unsalted)
    no_sealed = entry("xx", ks(1, 1, 1)).model_dump(by_alias=True)
    no_sealed["sealed"] = no_sealed["sealed"][:3]
    with pytest.raises(ValueError, match="sealed cells must be exactly"):
        Entry.model_validate(no_sealed)


# ------------------------------------------------------------------------------ reads and writes
def test_corrupt_board_is_refused_and_never_overwritten(board: Path):
    board.write_bytes(b'{"format": "scftc-leaderboard/2", "entries": [')
    before = board.read_bytes()
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(board)])
    assert result.exit_code == 1
    assert f"leaderboard {board} is not valid JSON" in result.stderr and "git checkout" in result.stderr
    assert not result.stderr.startswith("\n")
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


def test_reading_a_board_leaves_no_lock_file(tmp_path: Path):
    """A read takes the lock only to sweep a killed writer's temporary file: a plain read, of a
    board or of a path where none is, leaves nothing beside it (an installed package's folder
    stays untouched)."""
    path = tmp_path / "leaderboard" / "scftc-v1.json"
    update_board(path, lambda b: b.model_copy(update={"rounds": [round_one()]}))
    (tmp_path / "leaderboard" / "scftc-v1.json.lock").unlink()
    read_board(path)
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(path)])
    assert result.exit_code == 0, result.output
    nowhere = tmp_path / "leaderboard" / "nope.json"
    missing = runner.invoke(app, ["leaderboard", "--leaderboard", str(nowhere)])
    assert missing.exit_code == 1
    assert sorted(p.name for p in path.parent.iterdir()) == ["scftc-v1.json"]


def _write_slowly_then_hang(path: str) -> None:
    """Take the lock, leave a temporary file as a writer would, and hang (to be killed -9)."""
    from filelock import FileLock

    with FileLock(f"{path}.lock"):
        Path(path).with_name(f".{Path(path).name}.abc123.tmp").write_text('{"half": ')
        time.sleep(600)


def test_a_writer_killed_mid_write_leaves_no_temporary_file_and_no_stale_lock(board: Path):
    ctx = multiprocessing.get_context("spawn")
    proc = ctx.Process(target=_write_slowly_then_hang, args=(str(board),))
    proc.start()
    deadline = time.monotonic() + 30
    temp = board.with_name(f".{board.name}.abc123.tmp")
    while not temp.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert temp.exists()
    os.kill(proc.pid, signal.SIGKILL)
    proc.join(10)
    before = read_board(board).version  # the next command: cleans up, and the lock is free
    assert not temp.exists()
    start = time.monotonic()
    assert update_board(board, lambda b: b).version == before + 1
    assert time.monotonic() - start < 5


def _append_copies(path: str, entry_json: str, names: list[str]) -> None:
    e = Entry.model_validate_json(entry_json)
    for name in names:
        store.update_board(
            Path(path),
            "scftc-v1",
            lambda b, n=name: b.model_copy(
                update={"entries": [*b.entries, e.model_copy(update={"name": n})]}
            ),
        )


def test_concurrent_writers_all_land(board: Path):
    start = read_board(board).version
    entry_json = entry("ww", ks(1, 1, 1)).model_dump_json(by_alias=True)
    ctx = multiprocessing.get_context("fork")
    procs = [
        ctx.Process(target=_append_copies, args=(str(board), entry_json, [f"w{i}_{j}" for j in range(5)]))
        for i in range(3)
    ]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
        assert p.exitcode == 0
    final = read_board(board)
    assert final.version == start + 15
    assert {f"w{i}_{j}" for i in range(3) for j in range(5)} <= {e.name for e in final.entries}


# ------------------------------------------------------------------------------ removal, history
def test_remove_takes_an_entry_off_and_keeps_the_reason(board: Path):
    version = read_board(board).version
    result = runner.invoke(
        app,
        [
            "leaderboard",
            "remove",
            "beta",
            "--reason",
            "non-deterministic on verify",
            "--leaderboard",
            str(board),
        ],
    )
    assert result.exit_code == 0, result.output
    after = read_board(board)
    assert after.version == version + 1 and [e.name for e in after.entries] == ["alpha"]
    event = after.history[-1]
    assert (event.action, event.name, event.reason, event.board_version) == (
        "removed",
        "beta",
        "non-deterministic on verify",
        version + 1,
    )
    assert "removed `beta` (round 1): non-deterministic on verify" in board_markdown(after)
    with pytest.raises(UnknownNameError, match="alpha"):
        remove(board, "scftc-v1", "gamma", "typo")
    with pytest.raises(LeaderboardError, match="--reason"):
        remove(board, "scftc-v1", "alpha", "  ")
    assert read_board(board).version == version + 1


# ------------------------------------------------------------------- options before a subcommand
@pytest.mark.parametrize(
    "sub", [["remove", "beta", "--reason", "r"], ["verify"], ["rebuild", "--only", "pd"]]
)
def test_group_options_work_before_or_after_the_subcommand_and_conflicts_are_refused(
    sub: list[str], board: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    import scftc_cli.board.ops as ops
    import scftc_cli.board.verify as verifying

    seen: list[Path] = []
    monkeypatch.setattr(verifying, "verify", lambda path, *a, **k: seen.append(path) or _report(path))
    monkeypatch.setattr(
        ops, "rebuild", lambda path, *a, **k: seen.append(path) or ops.RebuildReport(None, {})
    )
    monkeypatch.setenv("SCFTC_ROUND_KEY", "00" * 32)
    other = tmp_path / "other.json"
    for args in (
        ["leaderboard", "--leaderboard", str(board), *sub],
        ["leaderboard", *sub, "--leaderboard", str(board)],
    ):
        if sub[0] == "remove":
            update_board(
                board,
                lambda b: b.model_copy(
                    update={
                        "rounds": [round_one()],
                        "entries": [entry("alpha", ks(1, 1, 1)), entry("beta", ks(1, 1, 1))],
                    }
                ),
            )
        result = runner.invoke(app, args)
        assert result.exit_code == 0, (args, result.output)
        if sub[0] != "remove":
            assert seen.pop() == board
    result = runner.invoke(
        app, ["leaderboard", "--leaderboard", str(board), *sub, "--leaderboard", str(other)]
    )
    assert result.exit_code == 2 and "given twice with different values" in result.stderr
    result = runner.invoke(app, ["leaderboard", "--format", "json", *sub, "--leaderboard", str(board)])
    assert result.exit_code == 2 and "apply to showing the board" in result.stderr


def _report(path: Path):
    from scftc_cli.board.verify import VerifyReport

    return VerifyReport(read_board(path))


def test_showing_a_missing_board_says_how_to_create_it(tmp_path: Path):
    missing = tmp_path / "none.json"
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(missing)])
    assert result.exit_code == 1 and f"no leaderboard at {missing}" in result.stderr
    assert "scftc leaderboard open" in result.stderr and "--key-file" in result.stderr


def test_help_shows_flags_as_flags():
    result = runner.invoke(app, ["submit", "--help"])
    assert "--dry-run " in result.stdout and "<bool>" not in result.stdout


def test_sigterm_during_a_write_unwinds_and_leaves_no_temporary_file(board: Path):
    """The command line turns SIGTERM into an orderly exit: the atomic write removes its temporary
    file on the way out, and the board is the old one, whole."""
    code = (
        "import sys, time\n"
        "import scftc_cli.board.store as s\n"
        "real_fsync = s.os.fsync\n"
        "def slow_fsync(fd):\n"
        "    print('writing', flush=True); time.sleep(60)\n"
        "s.os.fsync = slow_fsync\n"
        "from scftc_cli.commands.app import main\n"
        "sys.argv = ['scftc', 'leaderboard', 'remove', 'beta', '--reason', 'x', "
        f"'--leaderboard', {str(board)!r}]\n"
        "main()\n"
    )
    before = board.read_bytes()
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None and proc.stdout.readline().strip() == "writing"
    assert list(board.parent.glob(".scftc-v1.json.*.tmp"))  # mid-write: the temporary file exists
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(30) == 128 + signal.SIGTERM
    assert not list(board.parent.glob(".scftc-v1.json.*.tmp"))  # removed by the exiting writer itself
    assert board.read_bytes() == before


def test_a_round_key_is_written_0600_outside_every_repository_and_never_overwritten(tmp_path: Path):
    key = tmp_path / "keys" / "round.key"
    result = runner.invoke(app, ["leaderboard", "keygen", str(key)])
    assert result.exit_code == 0, result.output
    assert key.stat().st_mode & 0o777 == 0o600 and len(bytes.fromhex(key.read_text().strip())) == 32
    before = key.read_bytes()
    assert runner.invoke(app, ["leaderboard", "keygen", str(key)]).exit_code == 1  # never overwritten
    assert key.read_bytes() == before
    inside = Path(__file__).resolve().parents[2] / "a-round.key"
    result = runner.invoke(app, ["leaderboard", "keygen", str(inside)])
    assert result.exit_code == 2 and "inside a repository" in result.stderr and not inside.exists()
    key.chmod(0o644)
    result = runner.invoke(
        app, ["leaderboard", "open", "--leaderboard", str(tmp_path / "b.json"), "--key-file", str(key)]
    )
    assert result.exit_code == 1 and "chmod 600" in result.stderr
