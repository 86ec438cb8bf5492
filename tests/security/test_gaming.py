"""Gaming the board instead of the sandbox: a look-up table of the public draw, a controller that
is not deterministic, a tiny n. Each is refused with the board byte-identical, or accepted only as
what it is: ranked on its sealed draw, which no file can know in advance (the round's secret was
committed before the file was submitted and is revealed only when the round is sealed).
``tests/security/test_rounds.py`` plays the attacks on the rounds themselves."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.board.ops import abandon
from scftc_cli.board.ranking import rank_board
from scftc_cli.board.rounds import read_key, write_key
from scftc_cli.board.store import read_board
from scftc_cli.commands.app import app
from scftc_cli.versions.v1.sim.testbed import TESTBED
from scftc_cli.versions.v1.spec import V1

from .conftest import needs_sandbox

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()

MANIFEST = """SUBMISSION = {{
    "name": "{name}",
    "version": "0.1",
    "authors": ["Mallory"],
    "description": "{description}",
    "entry": "Ctl",
    "license": "MIT",
}}
"""

LOOKUP = '''
KP_S2, KD_S = 0.04, 0.14


def key(row):
    return repr(tuple(float(x) for x in np.round(row, 9)))


class Ctl:
    """Recognise a public episode by its first observation (exact on scftc-v1) and fly the bias
    oracle's law with the fault looked up; anything else gets the plain PD."""

    def reset(self, n, context):
        self.i0 = np.asarray(context.inertia_nominal_kgm2, dtype=float)
        self.tau = float(context.tau_max_nm)
        self.theta = None

    def act(self, obs):
        if self.theta is None:
            rows = [TABLE.get(key(o)) for o in obs]
            self.theta = np.array([r[:3] if r else (1.0, 1.0, 1.0) for r in rows])
            self.beta = np.array([r[3:] if r else (0.0, 0.0, 0.0) for r in rows])
        u0 = -self.i0 * (KP_S2 * obs[:, :3] + KD_S * obs[:, 3:]) / self.tau
        theta = np.where(np.abs(self.theta) < 0.05, np.copysign(0.05, self.theta), self.theta)
        return np.clip((u0 - self.beta) / theta, -1.0, 1.0)
'''


def lookup_source() -> str:
    """The attack of the class "look-up cheat": the public draw is pinned and anyone can
    regenerate it offline, so the file carries a table from each public held-out episode's first
    observation to its true fault (``theta``, ``beta``)."""
    table = {}
    for fault_class in V1.ranked_classes:
        episodes = TESTBED.draw("test", fault_class, None, V1.n_faults, V1.n_seeds)
        first = np.concatenate([episodes.sigma0, episodes.omega0_rad_s], axis=1)
        for row, theta, beta in zip(first, episodes.fault.theta, episodes.fault.beta, strict=True):
            key = repr(tuple(float(x) for x in np.round(row, 9)))
            table[key] = tuple(float(x) for x in (*theta, *beta))
    manifest = MANIFEST.format(name="lookup", description="looks its episodes up")
    return f"import numpy as np\n\n{manifest}\nTABLE = {table!r}\n{LOOKUP}"


@pytest.fixture
def key(tmp_path: Path) -> Path:
    return write_key(tmp_path / "keys" / "round.key")


@pytest.fixture
def committed_board(tmp_path: Path, key: Path) -> Path:
    """A copy of the committed scftc-v1 board (the real built-in entries, rls_dob among them) whose
    open round we replace by one we hold the key of (its round secret stays with the maintainers)."""
    path = tmp_path / "leaderboard" / "scftc-v1.json"
    path.parent.mkdir()
    shutil.copy(ROOT / "leaderboard" / "scftc-v1.json", path)
    abandon(path, V1.version, "a private copy for this test", read_key(key), "the test")
    return path


def submit(path: Path, board: Path, *extra: str):
    return runner.invoke(app, ["submit", str(path), "--leaderboard", str(board), *extra])


@needs_sandbox
@pytest.mark.slow
def test_a_lookup_of_the_public_draw_ranks_on_its_sealed_draw_below_rls_dob(
    tmp_path: Path, committed_board: Path, key: Path
):
    path = tmp_path / "lookup.py"
    path.write_text(lookup_source())
    result = submit(path, committed_board, "--seal", "--key-file", str(key))
    assert result.exit_code == 0, result.output

    ranking = rank_board(read_board(committed_board, V1.version))
    rows = {r.entry.name: r for r in ranking.deployable}
    cheat = rows["lookup"]
    public = {c.fault_class: c.settled.k for c in cheat.entry.public if c.sensor is None}
    sealed = {c.fault_class: c.settled.k for c in cheat.entry.sealed if c.sensor is None}
    # On the public draw it is the bias oracle; on its sealed draw, the PD it falls back to.
    assert public["sign"] == public["gain"] == V1.n_faults * V1.n_seeds
    assert all(sealed[c] == 0 for c in V1.ranked_classes), sealed
    assert cheat.flagged  # public beats sealed beyond the intervals, shown on the board
    assert cheat.rank > rows["rls_dob"].rank


@needs_sandbox
def test_a_controller_that_is_not_deterministic_is_refused_and_the_board_unchanged(
    tmp_path: Path, committed_board
):
    source = (
        "import os\nimport numpy as np\n\n"
        + MANIFEST.format(name="dice", description="rolls dice")
        + "\n\nclass Ctl:\n    def reset(self, n, context):\n        self.n = n\n\n"
        + "    def act(self, obs):\n"
        + "        seed = int.from_bytes(os.urandom(8), 'little')\n"
        + "        return np.random.default_rng(seed).uniform(-1, 1, (obs.shape[0], 3))\n"
    )
    path = tmp_path / "dice.py"
    path.write_text(source)
    before = committed_board.read_bytes()
    result = submit(path, committed_board)
    assert result.exit_code == 1, result.output
    assert "not deterministic" in result.stderr
    assert committed_board.read_bytes() == before


def test_a_tiny_n_never_reaches_the_board(tmp_path: Path, committed_board):
    path = tmp_path / "pd_again.py"
    example = ROOT / "submissions" / "example_pd_plus" / "pd_plus.py"
    path.write_text(example.read_text().replace('"name": "pd_plus"', '"name": "pd_again"'))
    before = committed_board.read_bytes()
    result = submit(path, committed_board, "--n-faults", "1", "--n-seeds", "1")
    assert result.exit_code == 2, result.output
    assert "--dry-run" in result.stderr
    assert committed_board.read_bytes() == before
