"""Training-seed spread: a learned controller's committed weights are one draw from its training
procedure, so the study flies every training seed's weights on the held-out cells and reports
each seed, the mean and the range.

The weights of further seeds sit beside the committed ones, ``seeds/<controller>/seed<k>.<ext>``
(with their ``.yaml`` provenance), each made by the committed command with only ``--seed`` changed;
seed 0's are the committed weights themselves. They are measured here, never chosen from: the
committed seed was fixed before any other was trained (``TrainingRecord`` on the board).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from scftc_cli.baselines.params import controller_from_artifact
from scftc_cli.distributed.refs import BuiltinRef
from scftc_cli.evaluate import Cell, board_cells, evaluate_cells
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.records import CellResult
from scftc_cli.registry import ControllerSpec
from scftc_cli.render import markdown_lines
from scftc_cli.spec import BenchmarkSpec

if TYPE_CHECKING:
    from scftc_cli.distributed.runner import Runner

SEED_FILE = re.compile(r"^seed(\d+)$")


def seed_artifacts(entry: ControllerSpec) -> dict[int, Path]:
    """``seed -> weights file`` of a learned built-in: seed 0 is the committed artifact, the others
    ``seeds/<name>/seed<k>.*`` beside it (``{}`` for a controller with no single weights file)."""
    if entry.family != "learned" or len(entry.artifacts) != 1:
        return {}
    (committed,) = entry.artifact_paths()
    found = {0: committed}
    folder = committed.parent / "seeds" / entry.name
    for path in sorted(folder.glob(f"seed*{committed.suffix}")) if folder.is_dir() else []:
        match = SEED_FILE.match(path.stem)
        if match and int(match.group(1)) != 0:
            found[int(match.group(1))] = path
    return dict(sorted(found.items()))


@dataclass(frozen=True)
class SeedSpread:
    """One learned controller's held-out settled rate per seed and cell."""

    controller: str
    cells: list[str]
    rates: dict[int, list[float]]  # seed -> settled rate per cell (fraction), in ``cells`` order
    pooled: dict[int, float]  # seed -> settled rate pooled over the ranked classes


def seed_spread(
    entry: ControllerSpec,
    spec: BenchmarkSpec,
    cells: list[Cell],
    progress: Progress = NO_PROGRESS,
    runner: Runner | None = None,
) -> SeedSpread | None:
    """Fly every seed's weights of ``entry`` on ``cells`` (full size), on ``runner``'s workers if
    given (the weights travel as bytes; bit-identical); ``None`` with fewer than two seeds."""
    artifacts = seed_artifacts(entry)
    if len(artifacts) < 2:
        return None
    rates: dict[int, list[float]] = {}
    pooled: dict[int, float] = {}
    for seed, path in artifacts.items():
        make: Callable[[], Controller] = entry.make if seed == 0 else controller_from_artifact(entry, path)

        def factory(_cell: Cell, make: Callable[[], Controller] = make) -> Controller:
            return make()

        artifact = None if seed == 0 else (path.name, path.read_bytes())
        runs = evaluate_cells(
            factory,
            spec,
            cells,
            progress=progress,
            label=f"{entry.name} seed {seed}",
            runner=runner,
            ref=BuiltinRef(entry.name, spec.version, artifact),
        )
        results: list[CellResult] = [run.result for run in runs]
        rates[seed] = [r.settled.rate for r in results]
        ranked = [r for r in results if r.sensor is None and r.fault_class in spec.ranked_classes]
        pooled[seed] = sum(r.settled.k for r in ranked) / sum(r.n for r in ranked)
    return SeedSpread(entry.name, [c.label for c in cells], rates, pooled)


def seeds_markdown(spec: BenchmarkSpec, spreads: list[SeedSpread]) -> str:
    """The training-seed table of every learned controller: one row per seed, then the mean and
    the range (min-max), held-out settled % per cell and pooled over the ranked classes."""
    out = [
        f"# Training-seed spread ({spec.version}, held-out split, settled %)",
        "",
        "Each learned controller retrained with seeds 1, 2, ... by its committed command with only "
        "`--seed` changed; seed 0 is the committed weights, fixed before any other seed was trained "
        "(nothing was chosen among the seeds). n = 500 episodes per cell.",
    ]
    for s in spreads:
        headers = ["seed", *s.cells, f"pooled ({', '.join(spec.ranked_classes)})"]
        rows = [
            [
                f"{seed}{' (committed)' if seed == 0 else ''}",
                *(f"{100 * r:.1f}" for r in rates),
                f"{100 * s.pooled[seed]:.1f}",
            ]
            for seed, rates in s.rates.items()
        ]
        table = np.array([[*rates, s.pooled[seed]] for seed, rates in s.rates.items()])
        rows.append(["mean", *(f"{100 * v:.1f}" for v in table.mean(axis=0))])
        rows.append(
            [
                "range",
                *(
                    f"{100 * lo:.1f}-{100 * hi:.1f}"
                    for lo, hi in zip(table.min(axis=0), table.max(axis=0), strict=True)
                ),
            ]
        )
        out += ["", f"## `{s.controller}` ({len(s.rates)} seeds)", "", *markdown_lines(headers, rows)]
    if not spreads:
        out += ["", "(no learned controller of this version has weights of more than one seed)"]
    return "\n".join(out) + "\n"


def write_seed_table(
    spec: BenchmarkSpec, out: Path, progress: Progress = NO_PROGRESS, runner: Runner | None = None
) -> Path:
    """Fly every learned controller's training seeds on the board's held-out cells (on ``runner``
    if given) and write ``training_seeds.md`` into ``out``."""
    from scftc_cli.registry import registry

    cells = board_cells(spec)
    learned = [e for e in registry(spec.version).values() if len(seed_artifacts(e)) > 1]
    progress.add_total(sum(len(seed_artifacts(e)) for e in learned) * len(cells) * spec.steps)
    spreads = [s for e in learned if (s := seed_spread(e, spec, cells, progress, runner)) is not None]
    out.mkdir(parents=True, exist_ok=True)
    path = out / "training_seeds.md"
    path.write_text(seeds_markdown(spec, spreads))
    return path
