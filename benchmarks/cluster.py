"""Serial vs a local Dask cluster (``--workers``), in one run: ``leaderboard verify`` of the
committed board and one 50 000-episode cell.

Run: ``python benchmarks/cluster.py [--benchmark scftc-v2] [--workers 2] [--out FILE]`` (default
file ``benchmarks/results/cluster.json``, or ``cluster-<version>.json`` for another version)

(Not ``dask.py``: run as a script, a file of that name beside it would shadow the ``dask`` package.)

Wall times include the cluster's start-up (what a user pays for ``--workers``); the peak resident
memory of each worker process is read on the workers after the runs. The cell results are
compared bit for bit with the serial run. On a 2-core machine the speed-up is bounded by the cores.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import time
from pathlib import Path

from scftc_cli.board.flights import Scoring
from scftc_cli.board.store import default_board_path
from scftc_cli.board.verify import verify
from scftc_cli.distributed.refs import BuiltinRef
from scftc_cli.distributed.runner import cluster
from scftc_cli.evaluate import Cell, evaluate_cells
from scftc_cli.registry import make_controller
from scftc_cli.spec import get_spec
from scftc_cli.versions import version_names

BIG = (500, 100)  # 50 000 episodes


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--benchmark", choices=version_names(), default=version_names()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    first = args.benchmark == version_names()[0]
    out = args.out or Path(f"benchmarks/results/cluster{'' if first else '-' + args.benchmark}.json")
    spec = get_spec(args.benchmark)
    board = default_board_path(spec.version)
    cell = [Cell("test", "gain_bias")]
    doc: dict = {
        "machine": platform.processor() or platform.machine(),
        "benchmark": spec.version,
        "workers": args.workers,
    }

    start = time.perf_counter()
    serial_report = verify(board, Scoring(spec))
    doc["verify_serial_s"] = time.perf_counter() - start
    start = time.perf_counter()
    serial_cell = evaluate_cells(
        lambda _c: make_controller("rls_dob", spec.version), spec, cell, n_faults=BIG[0], n_seeds=BIG[1]
    )
    doc["cell_50k_serial_s"] = time.perf_counter() - start
    doc["serial_peak_rss_mb"] = peak_rss_mb()

    start = time.perf_counter()
    with cluster(workers=args.workers) as runner:
        assert runner is not None
        started = time.perf_counter()
        doc["cluster_start_s"] = started - start
        cluster_report = verify(board, Scoring(spec, runner=runner))
        doc["verify_cluster_s"] = time.perf_counter() - start
        start = time.perf_counter()
        ref = BuiltinRef("rls_dob", spec.version)
        cluster_cell = evaluate_cells(
            lambda _c: make_controller("rls_dob", spec.version),
            spec,
            cell,
            n_faults=BIG[0],
            n_seeds=BIG[1],
            runner=runner,
            ref=ref,
        )
        doc["cell_50k_cluster_s"] = time.perf_counter() - start
        doc["worker_peak_rss_mb"] = sorted(runner.client.run(peak_rss_mb).values())
    doc["verify_ok"] = serial_report.ok and cluster_report.ok
    doc["cell_identical"] = cluster_cell[0].result == serial_cell[0].result and all(
        (getattr(cluster_cell[0].outcomes, f) == getattr(serial_cell[0].outcomes, f)).all()
        for f in ("settled", "final_error_deg")
    )
    doc["verify_speedup"] = doc["verify_serial_s"] / doc["verify_cluster_s"]
    doc["cell_speedup"] = doc["cell_50k_serial_s"] / doc["cell_50k_cluster_s"]
    for key, value in doc.items():
        print(f"{key}: {value:.2f}" if isinstance(value, float) else f"{key}: {value}")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
