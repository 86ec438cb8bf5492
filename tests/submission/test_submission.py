"""Submissions: the manifest, the sandbox, and every kind of bad input through ``scftc submit``.

Every rejection must exit 1 with a one-line reason that names the fix, and leave the leaderboard
byte-for-byte unchanged. Cells are tiny (1 fault x 1 seed) so each test takes about a second.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.board.ops import Scoring, builtin_entry
from scftc_cli.board.store import read_board as _read_board
from scftc_cli.board.store import update_board as _update_board
from scftc_cli.commands.app import app
from scftc_cli.errors import SubmissionRejected
from scftc_cli.sim.v1 import public_context
from scftc_cli.spec import V1
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.submission.manifest import SubmissionManifest, load_submission
from scftc_cli.submission.sandbox import Sandbox


def read_board(path: Path):
    return _read_board(path, V1.version)


def update_board(path: Path, change):
    return _update_board(path, V1.version, change)


runner = CliRunner()
EXAMPLE = Path(__file__).resolve().parents[2] / "submissions" / "example_pd_plus" / "pd_plus.py"
TINY = ["--n-faults", "1", "--n-seeds", "1"]

MANIFEST = """SUBMISSION = {{
    "name": "{name}",
    "version": "0.1",
    "authors": ["Test Author"],
    "description": "a test submission",
    "entry": "Ctl",
    "license": "MIT",
}}
"""


def write_submission(
    folder: Path,
    act: str = "return np.zeros((obs.shape[0], 3))",
    *,
    name: str = "probe",
    header: str = "",
    manifest: str | None = None,
    reset: str = "self.n = n",
) -> Path:
    """A submission file whose ``act`` body is ``act`` (indented for the method)."""
    body = textwrap.indent(textwrap.dedent(act).strip(), " " * 8)
    source = (
        "import numpy as np\n"
        + header
        + "\n"
        + (MANIFEST.format(name=name) if manifest is None else manifest)
        + "\n\nclass Ctl:\n"
        + f"    def reset(self, n, context):\n        {reset}\n\n"
        + f"    def act(self, obs):\n{body}\n"
    )
    path = folder / f"{name}.py"
    path.write_text(source)
    return path


@pytest.fixture(scope="module")
def board_bytes(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    path = tmp_path_factory.mktemp("board") / "scftc-v1.json"
    entry = builtin_entry("pd", Scoring(V1, n_faults=1, n_seeds=1))
    update_board(path, lambda b: b.model_copy(update={"entries": [entry]}))
    return path.read_bytes()


@pytest.fixture
def board(tmp_path: Path, board_bytes: bytes) -> Path:
    """A board holding one tiny built-in entry (so 'unchanged' means something)."""
    path = tmp_path / "leaderboard" / "scftc-v1.json"
    path.parent.mkdir()
    path.write_bytes(board_bytes)
    return path


def submit(path: Path, board: Path, *extra: str):
    return runner.invoke(app, ["submit", str(path), "--leaderboard", str(board), *TINY, *extra])


def assert_rejected(result, board: Path, before: bytes, *fragments: str) -> str:
    """Exit 1, one error line containing ``fragments``, board untouched; returns the line."""
    assert result.exit_code == 1, (result.exit_code, result.output)
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    (line,) = lines
    assert line.startswith("error:")
    for fragment in fragments:
        assert fragment in line, (fragment, line)
    assert board.read_bytes() == before
    return line


# --------------------------------------------------------------------------------------- manifest
def test_example_submission_is_valid():
    sub = load_submission(EXAMPLE)
    assert sub.manifest.name == "pd_plus"
    assert sub.manifest.entry == "PDPlus"
    assert sub.imports == ("__future__", "numpy")
    assert len(sub.sha256) == 64


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        ({"name": "Bad Name!"}, "name"),
        ({"authors": []}, "authors"),
        ({"license": ""}, "license"),
        ({"paper_url": "not a url"}, "paper_url"),
        ({"surprise": 1}, "surprise"),
        ({"privileged": True}, "never be privileged"),
    ],
)
def test_manifest_model_rejects(change: dict, fragment: str):
    base = dict(name="ok_name", version="1", authors=["a"], description="d", entry="C", license="MIT")
    with pytest.raises(ValueError, match=fragment):
        SubmissionManifest.model_validate({**base, **change})


def test_manifest_is_read_without_running_the_file(tmp_path: Path):
    # Module-level code that would blow up if imported: load_submission only parses.
    path = write_submission(tmp_path, header="raise SystemExit('imported!')\n")
    assert load_submission(path).manifest.name == "probe"


def test_non_literal_manifest_is_rejected(tmp_path: Path):
    manifest = "SUBMISSION = dict(name='x')\n"
    with pytest.raises(SubmissionRejected, match="plain dict literal"):
        load_submission(write_submission(tmp_path, manifest=manifest))


def test_missing_entry_class_is_rejected(tmp_path: Path):
    manifest = MANIFEST.format(name="probe").replace('"Ctl"', '"Missing"')
    with pytest.raises(SubmissionRejected, match="entry class `Missing`"):
        load_submission(write_submission(tmp_path, manifest=manifest))


# ------------------------------------------------------------------------------------ bad inputs
def test_syntax_error(tmp_path: Path, board: Path):
    before = board.read_bytes()
    path = write_submission(tmp_path, act="return (")
    assert_rejected(submit(path, board), board, before, "syntax error at line", "fix the Python syntax")


def test_import_error(tmp_path: Path, board: Path):
    before = board.read_bytes()
    path = write_submission(tmp_path, header="import no_such_module_xyz\n")
    assert_rejected(
        submit(path, board), board, before, "failed to import", "no_such_module_xyz", "fix the import"
    )


def test_no_manifest(tmp_path: Path, board: Path):
    before = board.read_bytes()
    path = write_submission(tmp_path, manifest="")
    assert_rejected(submit(path, board), board, before, "no SUBMISSION manifest", "add a top-level")


def test_invalid_manifest(tmp_path: Path, board: Path):
    before = board.read_bytes()
    manifest = MANIFEST.format(name="probe").replace('"authors": ["Test Author"],', "")
    path = write_submission(tmp_path, manifest=manifest)
    assert_rejected(submit(path, board), board, before, "invalid SUBMISSION manifest", "authors", "fix it")


@pytest.mark.parametrize("name", ["pd", "teacher"])
def test_duplicate_name(tmp_path: Path, board: Path, name: str):
    # `pd` is on the board; `teacher` is a built-in name even though this board lacks it.
    before = board.read_bytes()
    path = write_submission(tmp_path, name=name)
    assert_rejected(submit(path, board), board, before, f"name `{name}`", "choose another")


def test_privileged_claim_in_manifest(tmp_path: Path, board: Path):
    before = board.read_bytes()
    manifest = MANIFEST.format(name="probe").replace(
        '"license": "MIT",', '"license": "MIT", "privileged": True,'
    )
    path = write_submission(tmp_path, manifest=manifest)
    assert_rejected(submit(path, board), board, before, "privileged", "remove `privileged`")


def test_privileged_claim_in_class(tmp_path: Path, board: Path):
    before = board.read_bytes()
    path = write_submission(tmp_path)
    path.write_text(path.read_text().replace("class Ctl:\n", "class Ctl:\n    privileged = True\n"))
    assert_rejected(submit(path, board), board, before, "privileged", "remove `privileged`")


def test_privileged_claim_set_at_runtime(tmp_path: Path, board: Path):
    # Not visible to the static check: the sandbox catches it on the loaded class.
    before = board.read_bytes()
    path = write_submission(tmp_path)
    path.write_text(path.read_text() + "\nsetattr(Ctl, 'privi' + 'leged', 1)\n")
    assert_rejected(submit(path, board), board, before, "privileged", "remove `privileged`")


def test_exception_in_act(tmp_path: Path, board: Path):
    before = board.read_bytes()
    path = write_submission(tmp_path, act="return 1 / 0")
    assert_rejected(
        submit(path, board),
        board,
        before,
        "ZeroDivisionError",
        "probe.py line",
        "step 0",
        "fix the exception",
    )


@pytest.mark.parametrize("bad", ["np.nan", "np.inf"])
def test_non_finite_commands(tmp_path: Path, board: Path, bad: str):
    before = board.read_bytes()
    path = write_submission(tmp_path, act=f"return np.full((obs.shape[0], 3), {bad})")
    assert_rejected(submit(path, board), board, before, "NaN or inf", "finite values")


@pytest.mark.parametrize(
    ("act", "fragment"),
    [
        ("return np.zeros((obs.shape[0], 2))", "must return shape (1, 3), got (1, 2)"),
        ("return np.zeros(3)", "must return shape (1, 3), got (3,)"),
        ("return np.zeros((obs.shape[0], 3), dtype=np.int64)", "must return a float array, got dtype <i8"),
        ("return [[0.0, 0.0, 0.0]]", "must return a numpy array, got list"),
    ],
)
def test_wrong_shape_or_dtype(tmp_path: Path, board: Path, act: str, fragment: str):
    before = board.read_bytes()
    path = write_submission(tmp_path, act=act)
    assert_rejected(submit(path, board), board, before, fragment, "fix it")


def test_hang_hits_the_step_timeout(tmp_path: Path, board: Path):
    before = board.read_bytes()
    path = write_submission(tmp_path, act="import time\ntime.sleep(60)\nreturn np.zeros((obs.shape[0], 3))")
    result = submit(path, board, "--step-timeout", "0.5")
    assert_rejected(result, board, before, "took longer than 0.5 s", "per-step time limit")


def test_runaway_memory_hits_the_memory_limit(tmp_path: Path, board: Path):
    before = board.read_bytes()
    act = "self.hog = getattr(self, 'hog', []) + [np.empty(300_000_000)]\nreturn np.zeros((obs.shape[0], 3))"
    result = submit(write_submission(tmp_path, act=act), board, "--memory-mb", "512")
    assert_rejected(result, board, before, "out of memory", "512 MiB", "memory bounded")


def test_cpu_limit_kills_a_busy_loop(tmp_path: Path, board: Path):
    before = board.read_bytes()
    act = "while True:\n    pass"
    result = submit(write_submission(tmp_path, act=act), board, "--cpu-s", "2", "--step-timeout", "60")
    assert_rejected(result, board, before, "CPU time limit of 2 s")


@pytest.mark.parametrize("mode", ["w", "a", "r+"])
def test_opening_the_leaderboard_for_writing(tmp_path: Path, board: Path, mode: str):
    before = board.read_bytes()
    act = f"open({str(board)!r}, {mode!r}).write('x')\nreturn np.zeros((obs.shape[0], 3))"
    line = assert_rejected(
        submit(write_submission(tmp_path, act=act), board), board, before, "sandbox violation"
    )
    assert "for writing" in line and "remove the file" in line


def test_writing_the_leaderboard_cannot_be_caught(tmp_path: Path, board: Path):
    # The guard ends the child at once: swallowing the PermissionError does not help.
    before = board.read_bytes()
    act = (
        "try:\n"
        f"    import os; fd = os.open({str(board)!r}, os.O_WRONLY)\n"
        "except BaseException:\n"
        "    pass\n"
        "return np.zeros((obs.shape[0], 3))"
    )
    assert_rejected(submit(write_submission(tmp_path, act=act), board), board, before, "sandbox violation")


def test_starting_a_process_is_a_violation(tmp_path: Path, board: Path):
    before = board.read_bytes()
    act = "import subprocess\nsubprocess.run(['true'])\nreturn np.zeros((obs.shape[0], 3))"
    assert_rejected(
        submit(write_submission(tmp_path, act=act), board), board, before, "start or signal a process"
    )


# ---------------------------------------------------------------------------------- the sandbox
def test_child_sees_no_secret_and_no_fault(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """The child's environment carries no secret; its context carries no fault; cwd is a temp dir."""
    monkeypatch.setenv("SCFTC_SECRET", "do-not-leak")
    act = """
        import os
        leaked = float('SCFTC_SECRET' in os.environ or 'do-not-leak' in repr(os.environ))
        return np.full((obs.shape[0], 3), leaked + 2 * float(self.fault is not None) + 4 * self.tmp)
    """
    reset = "self.fault = context.fault; import os; self.tmp = float('scftc-sandbox-' in os.getcwd())"
    sub = load_submission(write_submission(tmp_path, act=act, reset=reset))
    with Sandbox(sub.source, sub.path.name, "Ctl", sub.imports) as box:
        box.reset(public_context(2), "test")
        out = box.act(np.zeros((2, 6)), "test")
    np.testing.assert_array_equal(out, np.full((2, 3), 4.0))


def test_reading_the_key_file_is_a_violation(tmp_path: Path):
    key = tmp_path / "key"
    key.write_text("secret")
    act = f"open({str(key)!r}).read()\nreturn np.zeros((obs.shape[0], 3))"
    sub = load_submission(write_submission(tmp_path, act=act))
    with Sandbox(sub.source, sub.path.name, "Ctl", sub.imports, SandboxLimits(), (key,)) as box:
        box.reset(public_context(1), "test")
        with pytest.raises(SubmissionRejected, match="private-draw key"):
            box.act(np.zeros((1, 6)), "test")


def test_print_does_not_corrupt_the_protocol(tmp_path: Path):
    act = "print('hello' * 1000)\nreturn np.ones((obs.shape[0], 3), dtype=np.float32) * 0.5"
    sub = load_submission(write_submission(tmp_path, act=act))
    with Sandbox(sub.source, sub.path.name, "Ctl", sub.imports) as box:
        box.reset(public_context(3), "test")
        out = box.act(np.zeros((3, 6)), "test")
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, np.full((3, 3), 0.5))


def test_dry_run_scores_without_writing(board: Path):
    before = board.read_bytes()
    result = submit(EXAMPLE, board, "--dry-run")
    assert result.exit_code == 0, result.output
    assert "dry run" in result.stdout and "pd_plus" in result.stdout
    assert board.read_bytes() == before


def test_submit_appends_one_entry_and_bumps_the_version(board: Path):
    version = read_board(board).version
    result = submit(EXAMPLE, board)
    assert result.exit_code == 0, result.output
    new = read_board(board)
    assert new.version == version + 1
    assert [e.name for e in new.entries] == ["pd", "pd_plus"]
    entry = new.entries[-1]
    assert entry.kind == "submission" and not entry.privileged
    assert entry.sha256 == load_submission(EXAMPLE).sha256
    assert entry.source == "pd_plus.py"  # outside the board's repo: just the file name
    assert entry.private is None and len(entry.public) == 10


def test_landlock_blocks_writes_exec_and_signals_where_the_kernel_has_it(tmp_path: Path):
    """The kernel layer under the audit hook (the hook alone is tested above)."""
    work = tmp_path / "work"
    work.mkdir()
    code = f"""
import os, sys
from scftc_cli.submission.child import _landlock
abi = _landlock({str(work)!r})
if abi == 0:
    sys.exit(42)
open({str(work / "inside")!r}, "w").write("ok")
attempts = [lambda: open({str(tmp_path / "outside")!r}, "w"), lambda: os.execv("/bin/true", ["true"])]
if abi >= 6:  # signal scoping
    attempts.append(lambda: os.kill(os.getppid(), 0))
for attempt in attempts:
    try:
        attempt()
        sys.exit(1)
    except OSError:
        pass
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    if result.returncode == 42:
        pytest.skip("this kernel has no Landlock")
    assert result.returncode == 0, result.stderr
    assert (work / "inside").exists() and not (tmp_path / "outside").exists()


def test_a_rejected_submission_leaves_no_folder_or_process(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    import scftc_cli.submission.sandbox as sandbox_module

    made: list[Path] = []
    real_mkdtemp, real_popen = sandbox_module.tempfile.mkdtemp, sandbox_module.subprocess.Popen
    procs: list[subprocess.Popen] = []

    def mkdtemp(**kwargs: object) -> str:
        made.append(Path(real_mkdtemp(**kwargs)))
        return str(made[-1])

    def popen(*args: object, **kwargs: object) -> subprocess.Popen:
        procs.append(real_popen(*args, **kwargs))
        return procs[-1]

    monkeypatch.setattr(sandbox_module.tempfile, "mkdtemp", mkdtemp)
    monkeypatch.setattr(sandbox_module.subprocess, "Popen", popen)
    for header, act in (("import no_such_module_xyz\n", "return None"), ("", "import time\ntime.sleep(60)")):
        sub = load_submission(write_submission(tmp_path, act=act, header=header))
        with pytest.raises(SubmissionRejected):
            with Sandbox(
                sub.source, sub.path.name, "Ctl", sub.imports, SandboxLimits(step_timeout_s=0.3)
            ) as box:
                box.reset(public_context(1), "test")
                box.act(np.zeros((1, 6)), "test")
    assert len(made) == 2 and not any(p.exists() for p in made)
    assert len(procs) == 2 and all(p.poll() is not None for p in procs)
