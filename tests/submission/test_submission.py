"""Submissions: the manifest, the sandbox, and every kind of bad input through ``scftc submit``.

Every rejection must exit 1 with a one-line reason that names the fix, and leave the leaderboard
byte-for-byte unchanged. Flights are dry runs on tiny cells (1 fault x 1 seed), about a second
each. Attacks on the sandbox itself live in ``tests/security``.
"""

from __future__ import annotations

import json
import subprocess
import tempfile
import textwrap
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.board.ops import open_round
from scftc_cli.commands.app import app
from scftc_cli.errors import SubmissionRejected
from scftc_cli.submission import isolation
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.submission.manifest import (
    MAX_AUTHORS,
    SubmissionManifest,
    load_submission,
    terminal_safe,
)
from scftc_cli.submission.sandbox import OUTPUT_BYTES, Sandbox
from scftc_cli.versions.v1.sim.testbed import public_context
from scftc_cli.versions.v1.spec import V1
from tests.sandbox import needs_sandbox

runner = CliRunner()
EXAMPLE = Path(__file__).resolve().parents[2] / "submissions" / "example_pd_plus" / "pd_plus.py"
TINY = ["--dry-run", "--n-faults", "1", "--n-seeds", "1"]

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


@pytest.fixture
def board(tmp_path: Path) -> Path:
    """An (empty) board file, so that 'unchanged' means something."""
    path = tmp_path / "leaderboard" / "scftc-v1.json"
    open_round(path, V1.version, bytes(32))  # a board with round 1 open (a test key)
    return path


def submit(path: Path, board: Path, *extra: str, dry_run: bool = True):
    """``scftc submit``: by default a dry run on tiny cells (landing needs full-size cells)."""
    sizes = TINY if dry_run else []
    return runner.invoke(app, ["submit", str(path), "--leaderboard", str(board), *sizes, *extra])


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


def sandbox_for(path: Path, limits: SandboxLimits | None = None, **kwargs: object) -> Sandbox:
    sub = load_submission(path)
    return Sandbox(
        sub.source, sub.path.name, sub.manifest.entry, sub.imports, limits or SandboxLimits(), **kwargs
    )


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
        ({"version": "1" * 33}, "version"),
        ({"authors": ["a"] * (MAX_AUTHORS + 1)}, "authors"),
        ({"authors": ["x" * 101]}, "at most 100 characters"),
        ({"description": "d" * 501}, "description"),
        ({"license": "M" * 65}, "license"),
        ({"code_url": "https://example.org/" + "a" * 300}, "code_url"),
        ({"description": "looks \x1b[2J\x1b[Hinnocent"}, "U+001B"),
        ({"authors": ["Eve\x1b]0;pwned\x07"]}, "U+0007, U+001B"),
        ({"license": "MIT\r"}, "U+000D"),
        ({"paper_url": "https://example.org/\x9b31m"}, "U+009B"),
        ({"description": "tab\there"}, "U+0009"),
        ({"authors": ["Mallory\u202e"]}, "U+202E"),
        ({"license": "MIT\nGPL"}, "U+000A"),
        ({"benchmark": "scftc-v9"}, "unknown benchmark 'scftc-v9'; use one of scftc-v1"),
    ],
)
def test_manifest_model_rejects(change: dict, fragment: str):
    base = dict(name="ok_name", version="1", authors=["a"], description="d", entry="C", license="MIT")
    with pytest.raises(ValueError, match=fragment.replace("+", r"\+")):
        SubmissionManifest.model_validate({**base, **change})


def test_a_description_may_hold_plain_newlines():
    base = dict(name="ok_name", version="1", authors=["a"], entry="C", license="MIT")
    assert SubmissionManifest.model_validate({**base, "description": "one\ntwo"}).description == "one\ntwo"


@pytest.mark.parametrize(
    ("text", "shown"),
    [
        ("\x1b[31mred\x1b[0m", "red"),
        ("a\x1b]0;title\x07b", "ab"),
        ("a\x1b]8;;https://evil\x1b\\link\x1b]8;;\x1b\\b", "alinkb"),
        ("over\rwrite", "overwrite"),
        ("8-bit \x9b2J csi", "8-bit  csi"),
        ("bell\x07 nul\x00 del\x7f", "bell nul del"),
        ("bidi \u202eevil", "bidi evil"),
        ("unterminated \x1b]0;title", "unterminated "),
        ("tab\tand\nnewline", "tab\tand\nnewline"),
    ],
)
def test_terminal_safe_strips_escapes_and_controls(text: str, shown: str):
    assert terminal_safe(text) == shown


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


@pytest.mark.parametrize("coding", ["latin-1", "utf-7", "cp1252", "no-such-codec"])
def test_a_source_in_another_encoding_is_rejected(tmp_path: Path, coding: str):
    path = write_submission(tmp_path)
    path.write_bytes(f"# -*- coding: {coding} -*-\n".encode() + path.read_bytes())
    with pytest.raises(SubmissionRejected, match="UTF-8"):
        load_submission(path)


def test_a_bom_and_a_conflicting_coding_line_are_rejected(tmp_path: Path):
    path = write_submission(tmp_path)
    path.write_bytes(b"\xef\xbb\xbf# coding: latin-1\n" + path.read_bytes())
    with pytest.raises(SubmissionRejected, match="UTF-8"):
        load_submission(path)


@needs_sandbox
@pytest.mark.parametrize("prefix", [b"\xef\xbb\xbf", b"# -*- coding: utf-8 -*-\n", b"# coding: ascii\n"])
def test_a_bom_or_a_utf8_coding_line_reads_alike_in_parent_and_child(tmp_path: Path, prefix: bytes):
    # The manifest's non-ASCII text must be the same string on both sides.
    manifest = MANIFEST.format(name="probe").replace("Test Author", "Zo\u00eb")
    if b"ascii" in prefix:
        manifest = MANIFEST.format(name="probe")
    act = "return np.full((obs.shape[0], 3), float(len(SUBMISSION['authors'][0])))"
    path = write_submission(tmp_path, act=act, manifest=manifest)
    path.write_bytes(prefix + path.read_bytes())
    sub = load_submission(path)
    with sandbox_for(path) as box:
        box.reset(public_context(1), "test")
        out = box.act(np.zeros((1, 6)), "test")
    assert out[0, 0] == len(sub.manifest.authors[0])


# ------------------------------------------------------------------------------------ bad inputs
def test_syntax_error(tmp_path: Path, board: Path):
    before = board.read_bytes()
    path = write_submission(tmp_path, act="return (")
    assert_rejected(submit(path, board), board, before, "syntax error at line", "fix the Python syntax")


@needs_sandbox
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


def test_escape_sequences_in_the_manifest_are_rejected_and_never_echoed(tmp_path: Path, board: Path):
    before = board.read_bytes()
    manifest = MANIFEST.format(name="probe").replace("Test Author", "Eve\\x1b]0;pwned\\x07\\x1b[2J")
    path = write_submission(tmp_path, manifest=manifest)
    line = assert_rejected(submit(path, board), board, before, "invalid SUBMISSION manifest", "U+001B")
    assert "\x1b" not in line and "\x07" not in line


@pytest.mark.parametrize("name", ["pd", "teacher"])
def test_duplicate_name(tmp_path: Path, board: Path, name: str):
    # Both are built-in names: refused before anything flies, whatever the board holds.
    before = board.read_bytes()
    path = write_submission(tmp_path, name=name)
    assert_rejected(submit(path, board, dry_run=False), board, before, f"name `{name}`", "choose another")


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


@needs_sandbox
def test_privileged_claim_set_at_runtime(tmp_path: Path, board: Path):
    # Not visible to the static check: the sandbox catches it on the loaded class.
    before = board.read_bytes()
    path = write_submission(tmp_path)
    path.write_text(path.read_text() + "\nsetattr(Ctl, 'privi' + 'leged', 1)\n")
    assert_rejected(submit(path, board), board, before, "privileged", "remove `privileged`")


@needs_sandbox
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


@needs_sandbox
def test_escape_sequences_from_the_controller_never_reach_the_terminal(tmp_path: Path, board: Path):
    before = board.read_bytes()
    act = "raise ValueError('\\x1b]0;pwned\\x07\\x1b[2Jgone\\x9b31m')"
    line = assert_rejected(submit(write_submission(tmp_path, act=act), board), board, before, "ValueError")
    assert not any(c in line for c in "\x1b\x07\x9b") and "gone" in line


@needs_sandbox
@pytest.mark.parametrize("bad", ["np.nan", "np.inf"])
def test_non_finite_commands(tmp_path: Path, board: Path, bad: str):
    before = board.read_bytes()
    path = write_submission(tmp_path, act=f"return np.full((obs.shape[0], 3), {bad})")
    assert_rejected(submit(path, board), board, before, "NaN or inf", "finite values")


@needs_sandbox
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


@needs_sandbox
def test_hang_hits_the_step_timeout(tmp_path: Path, board: Path):
    before = board.read_bytes()
    path = write_submission(tmp_path, act="import time\ntime.sleep(60)\nreturn np.zeros((obs.shape[0], 3))")
    result = submit(path, board, "--step-timeout", "0.5")
    assert_rejected(result, board, before, "took longer than 0.5 s", "per-step time limit")


@needs_sandbox
def test_runaway_memory_hits_the_memory_limit(tmp_path: Path, board: Path):
    before = board.read_bytes()
    act = "self.hog = getattr(self, 'hog', []) + [np.empty(300_000_000)]\nreturn np.zeros((obs.shape[0], 3))"
    result = submit(write_submission(tmp_path, act=act), board, "--memory-mb", "512")
    assert_rejected(result, board, before, "out of memory", "512 MiB", "memory bounded")


@needs_sandbox
def test_cpu_limit_kills_a_busy_loop(tmp_path: Path, board: Path):
    before = board.read_bytes()
    act = "while True:\n    pass"
    result = submit(write_submission(tmp_path, act=act), board, "--cpu-s", "2", "--step-timeout", "60")
    assert_rejected(result, board, before, "CPU time limit of 2 s")


@needs_sandbox
@pytest.mark.parametrize("mode", ["w", "a", "r+"])
def test_opening_a_file_outside_tmp_for_writing(tmp_path: Path, board: Path, mode: str):
    # /submission/probe.py (its own file) exists only inside the sandbox, read-only.
    before = board.read_bytes()
    act = f"open('/submission/probe.py', {mode!r}).write('x')\nreturn np.zeros((obs.shape[0], 3))"
    line = assert_rejected(
        submit(write_submission(tmp_path, act=act), board), board, before, "sandbox violation"
    )
    assert "for writing" in line and "nothing is writable" in line and "remove the file" in line


@needs_sandbox
@pytest.mark.parametrize("mode", ["w", "a", "r+"])
def test_opening_the_leaderboard_for_writing(tmp_path: Path, board: Path, mode: str):
    # The board is not in the sandbox at all: its path (under the host's /tmp here, which the
    # sandbox replaces with its own) leads nowhere.
    before = board.read_bytes()
    act = f"open({str(board)!r}, {mode!r}).write('x')\nreturn np.zeros((obs.shape[0], 3))"
    line = assert_rejected(submit(write_submission(tmp_path, act=act), board), board, before)
    assert "for writing" in line or "FileNotFoundError" in line


@needs_sandbox
def test_a_violation_cannot_be_caught(tmp_path: Path, board: Path):
    # The audit hook ends the child at once: swallowing the error does not help.
    before = board.read_bytes()
    act = (
        "try:\n"
        "    import os; fd = os.open('/submission/probe.py', os.O_WRONLY)\n"
        "except BaseException:\n"
        "    pass\n"
        "return np.zeros((obs.shape[0], 3))"
    )
    assert_rejected(submit(write_submission(tmp_path, act=act), board), board, before, "sandbox violation")


@needs_sandbox
def test_starting_a_process_is_a_violation(tmp_path: Path, board: Path):
    before = board.read_bytes()
    act = "import subprocess\nsubprocess.run(['true'])\nreturn np.zeros((obs.shape[0], 3))"
    assert_rejected(
        submit(write_submission(tmp_path, act=act), board), board, before, "start or signal a process"
    )


@needs_sandbox
def test_opening_a_socket_is_a_violation(tmp_path: Path, board: Path):
    before = board.read_bytes()
    act = "import socket\nsocket.socket()\nreturn np.zeros((obs.shape[0], 3))"
    assert_rejected(
        submit(write_submission(tmp_path, act=act), board), board, before, "tried to open a network socket"
    )


@needs_sandbox
def test_a_refusal_by_the_kernel_is_named_as_such(tmp_path: Path, board: Path):
    # No audit event for mkfifo: the kernel's EPERM comes back as the sandbox's refusal.
    before = board.read_bytes()
    act = "import os\nos.mkfifo('/tmp/fifo')\nreturn np.zeros((obs.shape[0], 3))"
    assert_rejected(
        submit(write_submission(tmp_path, act=act), board),
        board,
        before,
        "the sandbox refused an operation",
        "PermissionError",
        "remove the file, process or network access",
    )


# ---------------------------------------------------------------------------------- the sandbox
@needs_sandbox
def test_child_sees_no_secret_and_no_fault(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """The child's environment carries nothing of ours; its context carries no fault; it works in
    its working folder, /tmp (read-only: nothing in the sandbox is writable)."""
    monkeypatch.setenv("SCFTC_SECRET", "do-not-leak")
    act = """
        import os
        leaked = float('SCFTC_SECRET' in os.environ or 'do-not-leak' in repr(os.environ))
        return np.full((obs.shape[0], 3), leaked + 2 * float(self.fault is not None) + 4 * self.tmp)
    """
    reset = "self.fault = context.fault; import os; self.tmp = float(os.getcwd() == '/tmp')"
    with sandbox_for(write_submission(tmp_path, act=act, reset=reset)) as box:
        box.reset(public_context(2), "test")
        out = box.act(np.zeros((2, 6)), "test")
    np.testing.assert_array_equal(out, np.full((2, 3), 4.0))


@needs_sandbox
def test_files_outside_the_sandbox_are_not_there(tmp_path: Path):
    key = tmp_path / "key"
    key.write_text("secret")
    act = f"""
        import os
        seen = os.path.exists({str(key)!r}) or os.path.exists({str(tmp_path)!r})
        return np.full((obs.shape[0], 3), float(seen))
    """
    with sandbox_for(write_submission(tmp_path, act=act)) as box:
        box.reset(public_context(1), "test")
        assert box.act(np.zeros((1, 6)), "test")[0, 0] == 0.0


@needs_sandbox
def test_print_does_not_corrupt_the_protocol(tmp_path: Path):
    act = "print('hello' * 1000)\nreturn np.ones((obs.shape[0], 3), dtype=np.float32) * 0.5"
    with sandbox_for(write_submission(tmp_path, act=act)) as box:
        box.reset(public_context(3), "test")
        for _ in range(40):  # more than a pipe's worth of output: the parent drains it
            out = box.act(np.zeros((3, 6)), "test")
        assert box.output().endswith("hello\n") and len(box.output()) <= OUTPUT_BYTES  # a bounded tail
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, np.full((3, 3), 0.5))


@needs_sandbox
def test_dry_run_scores_without_writing(board: Path):
    before = board.read_bytes()
    result = submit(EXAMPLE, board)
    assert result.exit_code == 0, result.output
    assert "dry run" in result.stdout
    assert board.read_bytes() == before


def test_an_unusable_sandbox_is_refused_with_the_fix(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(isolation, "bwrap_path", lambda: None)
    try:
        reason = isolation.sandbox_unavailable(refresh=True)
        assert reason is not None and "apt-get install -y bubblewrap" in reason
        with pytest.raises(SubmissionRejected, match="apt-get install -y bubblewrap"):
            sandbox_for(write_submission(tmp_path))
    finally:
        monkeypatch.undo()
        isolation.sandbox_unavailable(refresh=True)


@needs_sandbox
def test_a_rejected_submission_leaves_no_folder_or_process(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    import scftc_cli.submission.sandbox as sandbox_module

    real_popen = sandbox_module.subprocess.Popen
    procs: list[subprocess.Popen] = []

    def popen(*args: object, **kwargs: object) -> subprocess.Popen:
        procs.append(real_popen(*args, **kwargs))
        return procs[-1]

    def no_temporaries(*args: object, **kwargs: object) -> object:
        raise AssertionError("the sandbox must not create temporary files or folders")

    monkeypatch.setattr(sandbox_module.subprocess, "Popen", popen)
    for name in ("mkdtemp", "mkstemp", "NamedTemporaryFile", "TemporaryDirectory", "TemporaryFile"):
        monkeypatch.setattr(tempfile, name, no_temporaries)
    for header, act in (("import no_such_module_xyz\n", "return None"), ("", "import time\ntime.sleep(60)")):
        with pytest.raises(SubmissionRejected):
            with sandbox_for(
                write_submission(tmp_path, act=act, header=header), SandboxLimits(step_timeout_s=0.3)
            ) as box:
                box.reset(public_context(1), "test")
                box.act(np.zeros((1, 6)), "test")
    sandboxes = [p for p in procs if "scftc_cli.submission.child" in p.args]
    assert len(sandboxes) == 2 and all(p.returncode is not None for p in sandboxes)


@needs_sandbox
@pytest.mark.slow
def test_a_full_size_submission_lands_through_the_sandbox(tmp_path: Path, board: Path):
    """The whole path: determinism check, public and sealed draws at full size (about 10 s)."""
    path = tmp_path / "pd_plus_sandboxed.py"
    path.write_text(EXAMPLE.read_text().replace('"name": "pd_plus"', '"name": "pd_plus_sandboxed"'))
    result = submit(path, board, dry_run=False)
    assert result.exit_code == 0, result.output
    assert "added `pd_plus_sandboxed`" in result.stdout
    assert load_submission(path).sha256 in board.read_text()


@needs_sandbox
@pytest.mark.slow
def test_out_of_range_commands_are_clipped_on_every_path(tmp_path: Path, board: Path):
    """One rule, as docs/submitting.md says: the simulator clips every command to [-1, 1]. A
    controller that returns 2.0 is flown, not crashed, by eval, a dry run and a landing run alike,
    and gets the same numbers as the same law clipped by itself."""
    law = "u = -4.0 * obs[:, :3] - 8.0 * obs[:, 3:]\nu = np.where(np.abs(u) > 0.5, 2.0 * np.sign(u), u)\n"
    (tmp_path / "tame").mkdir()
    loud = write_submission(tmp_path, act=law + "return u", name="loud")
    tame = write_submission(tmp_path / "tame", act=law + "return np.clip(u, -1.0, 1.0)", name="tame")
    sizes = ["--class", "all", "--n-faults", "3", "--n-seeds", "2", "--format", "json"]
    flown = []
    for file in (loud, tame):
        result = runner.invoke(app, ["eval", "--controller-file", str(file), *sizes])
        assert result.exit_code == 0, result.output
        cells = json.loads(result.stdout)["cells"]
        flown.append([(c["class"], c["settled"]["k"], c["final_error_deg"]["median"]) for c in cells])
    assert flown[0] == flown[1]
    result = submit(loud, board, "--n-faults", "3", "--n-seeds", "2", "--dry-run")
    assert result.exit_code == 0, result.output
    result = submit(loud, board, dry_run=False)  # the landing run: whole-cell determinism check included
    assert result.exit_code == 0, result.output
    assert "added `loud`" in result.stdout


@pytest.mark.parametrize(
    ("name", "said"),
    [
        ("café", "`café` has `é`, which a name may not contain"),
        ("a" * 50, "is 50 characters long"),
        ("9abc", "must start with a letter"),
        ("Probe", "has `P`"),
    ],
)
def test_a_bad_name_is_explained_in_words_not_a_regex(tmp_path: Path, name: str, said: str):
    path = write_submission(tmp_path, manifest=MANIFEST.format(name=name), name="file")
    with pytest.raises(SubmissionRejected) as err:
        load_submission(path)
    assert said in str(err.value) and "2-40 chars" in str(err.value)
    assert "[a-z]" not in str(err.value)  # no regex
