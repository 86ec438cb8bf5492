"""Submissions: a Python file holding a controller class and a ``SUBMISSION`` manifest.

The parent process never imports a submitted file. It reads the source once (the bytes that are
hashed are the bytes that run), parses it with ``ast`` and reads the manifest with
``ast.literal_eval``; only the sandboxed child (``submission/child.py``) executes it, compiling
the same bytes (so a BOM or a coding line reads alike on both sides; any encoding but UTF-8 or
ASCII is refused).

Everything in the manifest ends up on the board and on terminals, so every string is bounded in
length and free of control characters and escape sequences; ``terminal_safe`` strips them from
anything else a submission controls before it is echoed.
"""

from __future__ import annotations

import ast
import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from scftc_cli.errors import NoSuchSubmission, SubmissionRejected
from scftc_cli.spec import DEFAULT_BENCHMARK
from scftc_cli.submission.wire import control_characters, source_encoding_problem
from scftc_cli.submission.wire import terminal_safe as terminal_safe  # the command line's import
from scftc_cli.versions import version_names

GUIDE = "docs/submitting.md"
NAME_PATTERN = r"^[a-z][a-z0-9_-]{1,39}$"
URL_PATTERN = r"^https?://\S+$"
MAX_SOURCE_BYTES = 1_000_000
MAX_AUTHORS = 20
MAX_AUTHOR_CHARS = 100
MAX_DESCRIPTION_CHARS = 500
MAX_LICENSE_CHARS = 64
MAX_URL_CHARS = 300
MAX_VERSION_CHARS = 32


class SubmissionManifest(BaseModel):
    """The ``SUBMISSION = {...}`` dict literal at the top level of a submitted file."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(
        pattern=NAME_PATTERN,
        description="Unique name on the board: lowercase slug, 2-40 chars of a-z, 0-9, '_' or '-'.",
    )
    version: str = Field(
        max_length=MAX_VERSION_CHARS,
        pattern=r"^[0-9A-Za-z][0-9A-Za-z.+_-]*$",
        description="Version of the submission, e.g. 1.0.0.",
    )
    authors: list[str] = Field(
        min_length=1, max_length=MAX_AUTHORS, description="Who wrote it, one string per author."
    )
    description: str = Field(
        min_length=1,
        max_length=MAX_DESCRIPTION_CHARS,
        description="One or two sentences: what it is (plain text; newlines allowed).",
    )
    entry: str = Field(
        pattern=r"^[A-Za-z_][A-Za-z0-9_]*$",
        description="Name of the controller class defined at the top level of the file.",
    )
    license: str = Field(
        min_length=1, max_length=MAX_LICENSE_CHARS, description="License of the code (SPDX id, e.g. MIT)."
    )
    paper_url: str | None = Field(
        default=None, max_length=MAX_URL_CHARS, pattern=URL_PATTERN, description="Optional paper link."
    )
    code_url: str | None = Field(
        default=None, max_length=MAX_URL_CHARS, pattern=URL_PATTERN, description="Optional code link."
    )
    benchmark: str = Field(
        default=DEFAULT_BENCHMARK,
        max_length=MAX_VERSION_CHARS,
        description="The benchmark version the controller flies (its observation and action shapes).",
    )
    privileged: bool = Field(
        default=False,
        description="Always false: submissions never see the true fault. Claiming true is rejected.",
    )

    @field_validator("authors")
    @classmethod
    def _authors_named(cls, authors: list[str]) -> list[str]:
        if any(not a.strip() for a in authors):
            raise ValueError("every author must be a non-empty string")
        if any(len(a) > MAX_AUTHOR_CHARS for a in authors):
            raise ValueError(f"every author must be at most {MAX_AUTHOR_CHARS} characters")
        for author in authors:
            _plain(author)
        return authors

    @field_validator("description")
    @classmethod
    def _description_plain(cls, text: str) -> str:
        return _plain(text, allow_newline=True)

    @field_validator("license", "paper_url", "code_url")
    @classmethod
    def _line_plain(cls, text: str | None) -> str | None:
        return None if text is None else _plain(text)

    @field_validator("benchmark")
    @classmethod
    def _known_benchmark(cls, version: str) -> str:
        if version not in version_names():
            raise ValueError(f"unknown benchmark {version!r}; use one of {', '.join(version_names())}")
        return version

    @field_validator("privileged")
    @classmethod
    def _never_privileged(cls, privileged: bool) -> bool:
        if privileged:
            raise ValueError(
                "submissions can never be privileged (only built-in oracles see the true fault); "
                "remove `privileged`"
            )
        return privileged


def _plain(text: str, allow_newline: bool = False) -> str:
    """``text`` unchanged, or a ``ValueError`` naming its control characters (an ANSI or OSC
    escape in a manifest would repaint the terminal of whoever lists the board)."""
    found = control_characters(text, allow_newline)
    if found:
        allowed = " (a plain newline is allowed)" if allow_newline else ""
        listed = ", ".join(found)
        raise ValueError(f"contains control or invisible characters ({listed}); remove them{allowed}")
    return text


@dataclass(frozen=True)
class Submission:
    """A parsed, validated submission file (never imported here).

    Attributes:
        path: where it was read from.
        source: the exact bytes that were hashed and will be run.
        sha256: hex digest of ``source``.
        manifest: the validated ``SUBMISSION`` dict.
        imports: module names the file imports (known packages are pre-loaded in the sandbox).
    """

    path: Path
    source: bytes
    sha256: str
    manifest: SubmissionManifest
    imports: tuple[str, ...]


def _reject(path: Path, reason: str) -> SubmissionRejected:
    return SubmissionRejected(terminal_safe(f"{path.name}: {reason}"))


def _manifest_node(tree: ast.Module) -> ast.expr | None:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "SUBMISSION" for t in node.targets
        ):
            return node.value
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            if node.target.id == "SUBMISSION" and node.value is not None:
                return node.value
    return None


def _class_claims_privilege(cls: ast.ClassDef) -> bool:
    """``privileged = <anything but False>`` in the class body (the sandbox re-checks at runtime)."""
    for node in cls.body:
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        value = getattr(node, "value", None)
        if any(isinstance(t, ast.Name) and t.id == "privileged" for t in targets) and value is not None:
            if not (isinstance(value, ast.Constant) and value.value is False):
                return True
    return False


def _imports(tree: ast.Module) -> tuple[str, ...]:
    """Absolute module names the file imports anywhere (``numpy``, ``scipy.linalg``...)."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return tuple(sorted(names))


def format_validation_error(err: ValidationError) -> str:
    """Pydantic errors as one line: ``field: message; field: message``."""
    parts = []
    for e in err.errors():
        where = ".".join(str(p) for p in e["loc"]) or "manifest"
        msg = e["msg"].removeprefix("Value error, ")
        if (
            e["type"] == "string_pattern_mismatch"
            and e["loc"]
            and e["loc"][0] in SubmissionManifest.model_fields
        ):
            msg = _pattern_problem(str(e["loc"][0]), str(e["input"]))
        parts.append(f"{where}: {msg}")
    return terminal_safe("; ".join(parts))


def _pattern_problem(field: str, value: str) -> str:
    """What is wrong with ``value`` for a pattern-checked manifest field, in words (the regex says
    nothing to a newcomer): the first character not allowed, or the length, then the rule."""
    rule = SubmissionManifest.model_fields[field].description or "see docs/submitting.md"
    shown = value if len(value) <= 40 else value[:37] + "..."
    if field == "name":
        bad = next(
            (c for c in value if not (c.isascii() and (c.islower() or c.isdigit() or c in "_-"))), None
        )
        if bad is not None:
            return f"`{shown}` has `{bad}`, which a name may not contain ({rule})"
        if not 2 <= len(value) <= 40:
            return f"`{shown}` is {len(value)} characters long ({rule})"
        return f"`{shown}` must start with a letter ({rule})"
    return f"`{shown}` is not allowed here ({rule})"


def parse_manifest(source: bytes, path: Path) -> tuple[SubmissionManifest, ast.Module]:
    """The validated manifest and syntax tree of ``source``; rejects with the fix in one line."""
    problem = source_encoding_problem(source)
    if problem is not None:
        fix = "save the file as UTF-8 (a BOM is fine) without any other coding line"
        raise _reject(path, f"{problem}; {fix}")
    try:
        tree = ast.parse(source, filename=path.name)
    except SyntaxError as err:
        where = f"line {err.lineno}" if err.lineno else "unknown line"
        raise _reject(path, f"syntax error at {where}: {err.msg}; fix the Python syntax") from None
    except ValueError as err:  # e.g. null bytes
        raise _reject(path, f"not a Python source file ({err}); submit a .py text file") from None
    node = _manifest_node(tree)
    if node is None:
        raise _reject(
            path, f"no SUBMISSION manifest; add a top-level `SUBMISSION = {{...}}` dict (see {GUIDE})"
        )
    try:
        raw: Any = ast.literal_eval(node)
    except ValueError:
        raise _reject(
            path, f"SUBMISSION must be a plain dict literal (strings, lists, None); see {GUIDE}"
        ) from None
    if not isinstance(raw, dict):
        raise _reject(path, f"SUBMISSION must be a dict, got {type(raw).__name__}; see {GUIDE}")
    if raw.get("privileged") not in (None, False):
        raise _reject(
            path,
            "claims to be privileged; submissions never see the true fault (only built-in oracles do): "
            "remove `privileged` from SUBMISSION",
        )
    try:
        manifest = SubmissionManifest.model_validate(raw)
    except ValidationError as err:
        raise _reject(
            path, f"invalid SUBMISSION manifest: {format_validation_error(err)}; fix it (see {GUIDE})"
        ) from None
    return manifest, tree


def load_submission(path: Path) -> Submission:
    """Read, hash and statically check a submission file without executing any of it."""
    path = Path(path)
    if path.is_dir():
        raise NoSuchSubmission(f"{path} is a folder, not a file; pass the submission .py file in it")
    if not path.is_file():
        raise NoSuchSubmission(f"no such file: {path}; pass the path of your submission .py file")
    if path.suffix != ".py":
        raise _reject(path, "a submission is a single .py file; rename it or point at the .py file")
    source = path.read_bytes()
    if len(source) > MAX_SOURCE_BYTES:
        raise _reject(path, f"larger than {MAX_SOURCE_BYTES} bytes; keep the submission a single small file")
    manifest, tree = parse_manifest(source, path)
    classes = {n.name: n for n in tree.body if isinstance(n, ast.ClassDef)}
    if manifest.entry not in classes:
        raise _reject(
            path,
            f"entry class `{manifest.entry}` is not defined at the top level; "
            "set SUBMISSION['entry'] to your controller class name",
        )
    if _class_claims_privilege(classes[manifest.entry]):
        raise _reject(
            path,
            f"class `{manifest.entry}` claims to be privileged; submissions never see the true fault: "
            "remove `privileged` from the class",
        )
    return Submission(
        path=path,
        source=source,
        sha256=hashlib.sha256(source).hexdigest(),
        manifest=manifest,
        imports=_imports(tree),
    )
