"""Leaderboard files: tamper-evident reads, atomic locked writes.

Every read validates the whole file (``board/models.py``), so a corrupt or hand-edited file is
refused with the fix, and never overwritten. Every write holds a ``filelock.FileLock`` (an OS
lock: a killed holder releases it), re-reads the board, increments its version, and replaces the
file atomically (temporary file, fsync, rename): readers see the old board or the new one, never
half of either. A temporary file a killed writer left behind is removed by the next command.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from filelock import FileLock, Timeout
from pydantic import ValidationError

from scftc_cli.board.models import Leaderboard, empty_board
from scftc_cli.errors import LeaderboardError, WrongBoard

LOCK_TIMEOUT_S = 300.0
FIX_CORRUPT = (
    "restore it from version control (`git checkout -- {path}`), or move it aside and re-score the "
    "built-ins through a new round (`scftc leaderboard rebuild{flag} --key-file KEY`; submissions must "
    "then be re-submitted)"
)


def utc_now() -> str:
    return dt.datetime.now(dt.UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")


PACKAGE_DIR = Path(__file__).resolve().parent.parent
PUBLISHED = PACKAGE_DIR / "published"
"""The published boards as package data (``scftc_cli/published`` is a link to the checkout's
``leaderboard/``, copied into every wheel): what an installed package reads by default."""


def repo_root() -> Path:
    return PACKAGE_DIR.parent


def checkout_root() -> Path | None:
    """The repository this package runs from (an editable install or the source tree), or
    ``None`` when it is an installed copy (in site-packages, with no ``leaderboard/`` beside it)."""
    root = repo_root()
    return root if (root / "pyproject.toml").is_file() and (root / "leaderboard").is_dir() else None


def user_board_dir() -> Path:
    """Where an installed package writes a user's boards unless told otherwise:
    ``$XDG_DATA_HOME/scftc/leaderboard`` (``~/.local/share/scftc/leaderboard``)."""
    data = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(data) / "scftc" / "leaderboard"


def default_board_path(benchmark: str, *, writing: bool = False) -> Path:
    """The board a command uses when not given ``--leaderboard``.

    ``leaderboard/<benchmark>.json`` under the current folder if it has a ``leaderboard/`` folder
    (a checkout, or a copy of one); else, in a checkout,
    the checkout's; else (an installed package) the published snapshot for reading and the user's
    board folder (``user_board_dir``) for writing, never the package itself.
    """
    name = f"{benchmark}.json"
    local = Path("leaderboard") / name
    if local.parent.is_dir():
        return local
    root = checkout_root()
    if root is not None:
        return root / "leaderboard" / name
    return user_board_dir() / name if writing else PUBLISHED / name


def where(path: Path) -> str:
    """``path``, and what it is when it is not a file the user named: the published snapshot."""
    path = Path(path)
    if checkout_root() is None and path.resolve().is_relative_to(PACKAGE_DIR):
        from scftc_cli import __version__

        return f"{path} (the published snapshot shipped with scftc {__version__}; read-only)"
    return str(path)


def refuse_package_path(path: Path) -> None:
    """Refuse to write a board inside the installed package (site-packages, or the package folder
    of a checkout): a board is written only where the user says, or in ``user_board_dir``."""
    import sysconfig

    real = Path(path).resolve()
    protected = {PACKAGE_DIR} | {Path(sysconfig.get_path(k)).resolve() for k in ("purelib", "platlib")}
    for top in protected:
        if real.is_relative_to(top):
            raise LeaderboardError(
                f"{path} lies inside the installed package ({top}); boards are written only where you say: "
                f"--leaderboard PATH (by default {user_board_dir()} for an installed package)"
            )


def default_submissions_dir(board_path: Path) -> Path:
    """``submissions/`` next to the board's folder (the repo root for the committed board)."""
    return board_path.resolve().parent.parent / "submissions"


def read_board(path: Path, benchmark: str, *, missing_ok: bool = False) -> Leaderboard:
    """The validated board of ``benchmark`` at ``path``; a missing one is empty only when
    ``missing_ok``."""
    path = Path(path)
    flag = f" --benchmark {benchmark} --leaderboard {path}"
    fix = FIX_CORRUPT.format(path=path, flag=flag)
    sweep_if_idle(path)
    if not path.exists():
        if missing_ok:
            return empty_board(benchmark)
        raise LeaderboardError(
            f"no leaderboard at {path}; create it with `scftc leaderboard open{flag} --key-file KEY` "
            "(a maintainer's round key: `scftc leaderboard keygen`)"
        )
    try:
        raw = json.loads(path.read_bytes())
    except (ValueError, UnicodeDecodeError) as err:
        raise LeaderboardError(
            f"leaderboard {path} is not valid JSON ({err}); {fix}; it was left untouched"
        ) from None
    try:
        board = Leaderboard.model_validate(raw)
    except ValidationError as err:
        first = err.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "document"
        msg = first["msg"].removeprefix("Value error, ")
        more = f" (+{err.error_count() - 1} more)" if err.error_count() > 1 else ""
        raise LeaderboardError(
            f"leaderboard {path} fails validation at {where}: {msg}{more}; it was corrupted or edited by "
            f"hand: {fix}; it was left untouched"
        ) from None
    if board.benchmark_version != benchmark:
        raise WrongBoard(
            f"leaderboard {path} is the {board.benchmark_version} board, not {benchmark}'s; "
            f"pass --benchmark {board.benchmark_version} or another --leaderboard"
        )
    return board


def board_text(board: Leaderboard) -> str:
    return json.dumps(board.model_dump(mode="json", by_alias=True), indent=1) + "\n"


def write_text_atomically(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file and a rename: no half-written file, ever."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _atomic_write(path, text)


def _atomic_write(path: Path, text: str) -> None:
    """Temporary file in the same folder, fsync, then ``os.replace``: readers see old or new."""
    mode = path.stat().st_mode & 0o777 if path.exists() else 0o644
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def _sweep_temporaries(path: Path) -> None:
    """Remove temporary board files a killed writer left behind (call only while holding the lock:
    no live writer can own one then)."""
    for stale in path.parent.glob(f".{path.name}.*.tmp"):
        stale.unlink(missing_ok=True)


def sweep_if_idle(path: Path) -> None:
    """Clean up after a killed writer when no writer is active (a lock that cannot be taken at
    once means one is, and its temporary file is not stale). Only where a temporary file lies: a
    read leaves no lock file behind (and none in a read-only package)."""
    if not path.parent.is_dir() or not any(path.parent.glob(f".{path.name}.*.tmp")):
        return
    try:
        with FileLock(f"{path}.lock", timeout=0):
            _sweep_temporaries(path)
    except (Timeout, OSError):
        pass


def update_board(
    path: Path,
    benchmark: str,
    change: Callable[[Leaderboard], Leaderboard],
    *,
    lock_timeout_s: float = LOCK_TIMEOUT_S,
) -> Leaderboard:
    """Apply ``change`` to the current board under the lock; write it with ``version + 1``."""
    path = Path(path)
    refuse_package_path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        with FileLock(f"{path}.lock", timeout=lock_timeout_s):
            _sweep_temporaries(path)
            current = read_board(path, benchmark, missing_ok=True)
            changed = change(current.model_copy(deep=True))
            new = Leaderboard.model_validate(
                {
                    **changed.model_dump(by_alias=True),
                    "version": current.version + 1,
                    "updated_utc": utc_now(),
                }
            )
            text = board_text(new)
            Leaderboard.model_validate_json(text)  # what lands on disk must read back
            _atomic_write(path, text)
            return new
    except Timeout:
        raise LeaderboardError(
            f"another process holds {path}.lock for more than {lock_timeout_s:g} s; wait for it to finish, "
            "or delete the lock file if no scftc process is running"
        ) from None
