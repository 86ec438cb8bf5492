"""Golden digests: the bits every built-in of every published version produces on a few pinned
episodes of each cell, committed as ``tests/golden/<version>.json``.

A digest is the sha256 of what scores an episode and what decides it: every clipped command of
every step, the final, dwell and minimum errors, the settling time, each window's dwell maximum and,
where the version scores a diagnosis, the health reports' trace, of the first ``N_FAULTS`` faults
and ``N_SEEDS`` seeds of every cell of every split (the public draw; the first faults and seeds of a
cell do not depend on how many are drawn). The cells of one controller fly as one batch, as the
board flies them (``evaluate.stacks``), so a controller costs one rollout.

A change that moves a frozen version's bits fails ``tests/golden/test_golden.py`` in seconds rather
than after a board's re-flight. A change meant to move them (a declared numerics epoch) rewrites the
files with::

    python -m tests.golden.digests --write            # every published version
    python -m tests.golden.digests --write scftc-v2   # one
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
N_FAULTS = 2
N_SEEDS = 1


def golden_path(version: str) -> Path:
    return HERE / f"{version}.json"


def cells_of(version: str) -> list:
    """Every cell of every split of ``version``: its actuator classes, then its sensor faults."""
    from scftc_cli.evaluate import select_cells
    from scftc_cli.versions import get_spec

    spec = get_spec(version)
    cells = []
    for split in spec.splits:
        cells += select_cells(spec, split, None, None)
        if spec.sensor_faults:
            cells += select_cells(spec, split, None, "all")
    return cells


def _feed(h: hashlib._Hash, name: str, value: object) -> None:
    """Adds a named array to ``h``: its dtype, shape and little-endian bytes (NaNs made one
    pattern, so that the digest reads the numbers, not a NaN's payload)."""
    if value is None:
        h.update(f"{name}:none;".encode())
        return
    array = np.asarray(value)
    if array.dtype.kind == "f":
        array = np.where(np.isnan(array), np.nan, array).astype("<f8")
    elif array.dtype.kind in "iub":
        array = array.astype("<i8")
    h.update(f"{name}:{array.dtype.str}:{array.shape};".encode())
    h.update(np.ascontiguousarray(array).tobytes())


def rollout_digest(flown) -> str:
    """The sha256 (first 16 hex digits) of one cell's ``Rollout`` (module docstring)."""
    h = hashlib.sha256()
    for name in ("commands", "final_error_deg", "dwell_max_error_deg", "min_error_deg", "settling_time_s"):
        _feed(h, name, getattr(flown, name))
    _feed(h, "window_dwell_max_deg", flown.window_dwell_max_deg)
    health = flown.health
    for name in ("first_alarm_step", "first_alarm_after_onset", "false_alarms", "final_codes"):
        _feed(h, f"health.{name}", None if health is None else getattr(health, name))
    return h.hexdigest()[:16]


def controller_digests(version: str, name: str) -> dict[str, str]:
    """``split/cell -> digest`` of the built-in ``name`` flying ``version``'s cells."""
    from scftc_cli.evaluate import stacks
    from scftc_cli.registry import controller_spec
    from scftc_cli.sim.rollout import rollout_parts
    from scftc_cli.sim.testbed import testbed

    bed = testbed(version)
    entry = controller_spec(name, version)
    cells = cells_of(version)
    out: dict[str, str] = {}
    for group in stacks(bed.spec, cells, N_FAULTS * N_SEEDS):
        members = [cells[i] for i in group]
        parts = [bed.draw(c.split, c.fault_class, c.sensor, N_FAULTS, N_SEEDS) for c in members]
        flown = rollout_parts(entry.make(), parts, record=True)
        for cell, rows in zip(members, flown, strict=True):
            out[f"{cell.split}/{cell.label}"] = rollout_digest(rows)
    return out


def version_digests(version: str, names: list[str] | None = None) -> dict[str, object]:
    """The golden file's document for ``version`` (every built-in, or ``names``)."""
    from scftc_cli.registry import registry

    names = list(registry(version)) if names is None else names
    return {
        "version": version,
        "episodes": {"n_faults": N_FAULTS, "n_seeds": N_SEEDS, "draw": "public"},
        "regenerate": f"python -m tests.golden.digests --write {version}",
        "digests": {name: controller_digests(version, name) for name in names},
    }


def main(argv: list[str] | None = None) -> int:
    from scftc_cli.versions import published_names

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("versions", nargs="*", help="published versions (default: every one)")
    parser.add_argument("--write", action="store_true", help="rewrite tests/golden/<version>.json")
    args = parser.parse_args(argv)
    versions = args.versions or list(published_names())
    moved = 0
    for version in versions:
        document = version_digests(version)
        path = golden_path(version)
        if args.write:
            path.write_text(json.dumps(document, indent=1) + "\n")
            print(f"wrote {path}")
            continue
        committed = json.loads(path.read_text())["digests"] if path.exists() else {}
        for name, cells in document["digests"].items():  # type: ignore[union-attr]
            for cell, digest in cells.items():
                if committed.get(name, {}).get(cell) != digest:
                    moved += 1
                    print(f"{version} {name} {cell}: {committed.get(name, {}).get(cell)} -> {digest}")
    print(f"{moved} digests differ from the committed ones" if not args.write else "done")
    return 1 if moved else 0


if __name__ == "__main__":
    sys.exit(main())
