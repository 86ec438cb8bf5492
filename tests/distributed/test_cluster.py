"""Evaluation, verification and tuning on a real Dask ``LocalCluster`` of two worker processes:
results bit-identical to the serial run whatever the chunking, a killed worker changes nothing,
an unreachable scheduler is one clear line."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

pytest.importorskip("distributed")

import scftc_cli.board.ops as ops
import scftc_cli.board.verify as verifying
import scftc_cli.distributed.runner as runner_module
from scftc_cli.board.flights import Scoring
from scftc_cli.board.rounds import new_key
from scftc_cli.board.verify import verify
from scftc_cli.commands.app import app
from scftc_cli.distributed.refs import BuiltinRef, SubmissionRef
from scftc_cli.distributed.runner import ChunkTask, Runner, StackTask, cluster, run_chunk, run_stack
from scftc_cli.errors import ScftcError
from scftc_cli.evaluate import Cell, evaluate_cells, select_cells
from scftc_cli.registry import make_controller, registry
from scftc_cli.training import TrainRequest, tuning
from scftc_cli.versions.v1.spec import V1
from tests.sandbox import needs_sandbox

runner_cli = CliRunner()
CELLS = select_cells(V1, "test", None, None) + [Cell("test", "sign", "bias_0.2")]


BEFORE_CLUSTER = os.environ.get("NUMBA_NUM_THREADS")


@pytest.fixture(scope="module")
def dask_runner():
    with cluster(workers=2) as runner:
        assert runner is not None
        yield runner


def _numba_threads() -> int:
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def test_each_worker_gets_its_share_of_the_cores_and_this_process_keeps_its_environment(dask_runner):
    """The workers' numba pools are sized to their share of the cores, and the parent's
    environment is untouched: a NUMBA_NUM_THREADS left here would make numba refuse to compile
    in this process once its threads run."""
    assert os.environ.get("NUMBA_NUM_THREADS") == BEFORE_CLUSTER
    share = max(1, (os.cpu_count() or 1) // 2)
    assert set(dask_runner.client.run(_numba_threads).values()) == {share}


def _malloc_trim() -> str | None:
    return os.environ.get("MALLOC_TRIM_THRESHOLD_")


def _checksum(job: tuple[np.ndarray, int]) -> float:
    data, k = job
    return float(data[k::7].sum())


def test_a_shared_argument_reaches_every_task_once_without_a_large_graph(dask_runner: Runner):
    """``Runner.share`` sends a large argument once; tasks holding its future in a tuple get the
    value (the study's figures), and Dask sends no 20 MB graph (its "Sending large graph" warning)."""
    import warnings

    data = np.arange(2_500_000, dtype=np.float64)  # 20 MB, like v3's study
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the large-graph warning would raise here
        shared = dask_runner.share(data)
        sums = dask_runner.map(_checksum, [(shared, k) for k in range(3)])
    assert sums == [_checksum((data, k)) for k in range(3)]


def test_workers_start_without_dasks_malloc_trim_threshold(dask_runner):
    """Dask sets MALLOC_TRIM_THRESHOLD_ in its workers, which turns off glibc's adaptive mmap
    threshold and made the numpy-heavy controllers fly twice as slowly there (docs/scaling.md)."""
    assert set(dask_runner.client.run(_malloc_trim).values()) == {None}
    assert _malloc_trim() is None  # nor is it left in this process


def _serial(name: str, n_faults: int, n_seeds: int):
    return evaluate_cells(lambda _c: make_controller(name), V1, CELLS, n_faults=n_faults, n_seeds=n_seeds)


def _same(a, b) -> None:
    for x, y in zip(a, b, strict=True):
        assert x.result == y.result
        for field in (
            "settled",
            "operational",
            "touch_once",
            "final_error_deg",
            "settling_time_s",
            "dwell_max_error_deg",
            "fault_index",  # ragged chunks cross fault boundaries: each episode keeps its fault
        ):
            np.testing.assert_array_equal(
                getattr(x.outcomes, field), getattr(y.outcomes, field), err_msg=field
            )


@pytest.mark.slow
@pytest.mark.parametrize("name", ["pd", "rls_dob", "rls_plan", "rma_dob"])
def test_chunked_cluster_runs_are_bit_identical_to_the_serial_run(name, dask_runner, monkeypatch):
    serial = _serial(name, 6, 4)
    for chunk in (24, 7):  # one chunk per cell, then ragged chunks across fault boundaries
        monkeypatch.setattr(runner_module, "CHUNK_EPISODES", chunk)
        ref = BuiltinRef(name, V1.version)
        runs = evaluate_cells(None, V1, CELLS, n_faults=6, n_seeds=4, runner=dask_runner, ref=ref)  # type: ignore[arg-type]
        _same(runs, serial)


@needs_sandbox
def test_a_submission_flown_in_turn_on_the_cluster_equals_its_serial_flight(dask_runner: Runner):
    """On a cluster a submission's cells are shared out over the workers, each share flown in turn
    by one sandbox: every cell equal to the flight of the whole draw in one sandbox in process."""
    from scftc_cli.board.flights import budget, fly_submission
    from scftc_cli.submission.manifest import load_submission

    sub = load_submission(Path(__file__).parents[2] / "submissions" / "example_pd_plus" / "pd_plus.py")
    scoring = Scoring(V1, n_faults=3, n_seeds=2)
    serial, _ = fly_submission(sub, scoring, b"", budget(scoring), CELLS)
    ref = SubmissionRef(sub.path.name, sub.source, scoring.limits)
    runs = evaluate_cells(None, V1, CELLS, n_faults=3, n_seeds=2, runner=dask_runner, ref=ref)  # type: ignore[arg-type]
    assert [r.result for r in runs] == serial


def test_prefetched_work_is_taken_by_map_not_submitted_again(dask_runner: Runner, monkeypatch):
    submitted: list[int] = []
    real = dask_runner.client.map

    def spy(fn, items, **kwargs):
        submitted.extend(items)
        return real(fn, items, **kwargs)

    monkeypatch.setattr(dask_runner.client, "map", spy)
    dask_runner.prefetch(abs, [-3, -1, -2, -1])  # a repeat runs once
    assert dask_runner.map(abs, [-1, -2, -3, -4]) == [1, 2, 3, 4]  # in the order asked
    assert submitted == [-3, -1, -2, -4]  # only -4 was not queued ahead
    dask_runner.prefetch(abs, [-5])
    dask_runner.discard()  # what no map took is dropped
    assert dask_runner.map(abs, [-5]) == [5]
    assert submitted[-1] == -5


def test_a_slice_of_a_cell_is_that_slice_of_the_whole_cell():
    ref = BuiltinRef("bias_oracle", V1.version)
    whole = run_chunk(ChunkTask(ref, V1.version, "test", "gain_bias", None, 5, 4, b"", "numpy", 0, 20))
    part = run_chunk(ChunkTask(ref, V1.version, "test", "gain_bias", None, 5, 4, b"", "numpy", 7, 13))
    np.testing.assert_array_equal(part.final_error_deg, whole.final_error_deg[7:13])


def test_a_detector_read_chunk_by_chunk_is_the_detector_read_on_the_whole_cell():
    """What a worker reads off the detector of each chunk it flew (``StackTask.reader``), joined in
    episode order (``DetectorReadings.take``), is the reading of the whole cell flown at once."""
    from scftc_cli.evaluate import Cell
    from scftc_cli.study.detection import DetectorReadings, read_detector
    from scftc_cli.versions import get_version
    from scftc_cli.versions.v2.spec import V2

    ref = BuiltinRef(get_version(V2.version).study.detector or "", V2.version)
    cell = Cell("test", "sign")

    def chunk(start: int, stop: int) -> StackTask:
        return StackTask(
            (ChunkTask(ref, V2.version, "test", "sign", None, 3, 2, b"", "numpy", start, stop),),
            read_detector,
        )

    whole, joined = DetectorReadings(), DetectorReadings()
    whole.take(cell, list(run_stack(chunk(0, 6)).readings))
    joined.take(cell, [r for part in (chunk(0, 2), chunk(2, 6)) for r in run_stack(part).readings])
    assert set(joined.stats) == {"sign"} and joined.stats["sign"]["faulted"].shape == (6,)
    for name, value in whole.stats["sign"].items():
        np.testing.assert_array_equal(joined.stats["sign"][name], value, err_msg=name)
    assert run_stack(StackTask(chunk(0, 2).parts)).readings == (None,)  # no reader, nothing read


@pytest.mark.slow
def test_a_worker_killed_mid_run_changes_nothing(dask_runner: Runner, monkeypatch):
    monkeypatch.setattr(runner_module, "CHUNK_EPISODES", 5)
    serial = _serial("rls_dob", 10, 5)
    pids = list(dask_runner.client.run(os.getpid).values())
    assert len(pids) == 2
    killed = {"done": False}
    real_map = Runner.map

    def map_and_kill(self, fn, items, progress=None, weight=lambda _i: 1.0):
        class KillAfterFirst:
            def advance(self, amount: float = 1.0) -> None:
                if not killed["done"]:
                    os.kill(pids[0], signal.SIGKILL)  # a worker process dies while tasks run
                    killed["done"] = True

            def describe(self, text: str) -> None:
                pass

        return real_map(self, fn, items, KillAfterFirst(), weight)

    monkeypatch.setattr(Runner, "map", map_and_kill)
    runs = evaluate_cells(
        None, V1, CELLS, n_faults=10, n_seeds=5, runner=dask_runner, ref=BuiltinRef("rls_dob", V1.version)
    )  # type: ignore[arg-type]
    assert killed["done"]
    _same(runs, serial)
    deadline = time.monotonic() + 60
    while len(dask_runner.client.scheduler_info()["workers"]) < 2 and time.monotonic() < deadline:
        time.sleep(0.5)  # the nanny restarts the worker for the next tests


@pytest.fixture
def impatient(monkeypatch):
    """A refused connection is retried until the timeout: one second is enough here."""
    monkeypatch.setattr(runner_module, "CONNECT_TIMEOUT", "1s")


def test_an_unreachable_scheduler_is_one_line_naming_the_address(impatient):
    with pytest.raises(ScftcError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        with cluster(scheduler="tcp://127.0.0.1:9"):
            pass
    result = runner_cli.invoke(app, ["eval", "--controller", "pd", "--scheduler", "tcp://127.0.0.1:9"])
    assert result.exit_code == 1
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "tcp://127.0.0.1:9" in lines[0]


def test_the_scheduler_can_come_from_the_environment(monkeypatch, impatient):
    monkeypatch.setenv("SCFTC_SCHEDULER", "tcp://127.0.0.1:9")
    result = runner_cli.invoke(app, ["eval", "--controller", "pd", "--n-faults", "1", "--n-seeds", "1"])
    assert result.exit_code == 1 and "tcp://127.0.0.1:9" in result.stderr


@pytest.mark.slow
def test_eval_with_workers_prints_the_serial_cells():
    args = [
        "eval",
        "--controller",
        "pd",
        "--class",
        "all",
        "--n-faults",
        "5",
        "--n-seeds",
        "2",
        "--format",
        "json",
    ]
    serial = json.loads(runner_cli.invoke(app, args).stdout)["cells"]
    result = runner_cli.invoke(app, [*args, "--workers", "2"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["cells"] == serial


@pytest.mark.slow
def test_verify_on_the_cluster_passes_and_catches_an_edit(dask_runner: Runner, tmp_path: Path, monkeypatch):
    small = {n: registry()[n] for n in ("pd", "teacher")}
    monkeypatch.setattr(ops, "registry", lambda _benchmark=None: small)
    monkeypatch.setattr(verifying, "registry", lambda _benchmark=None: small)
    board = tmp_path / "leaderboard" / "scftc-v1.json"
    report = ops.rebuild(board, Scoring(V1, runner=dask_runner), new_key())  # scored through a round
    assert report.seal is not None and report.seal.sealed == ["pd", "teacher"]
    assert verify(board, Scoring(V1, runner=dask_runner)).ok
    assert verify(board, Scoring(V1)).ok  # scored on the cluster, verified in process: the same numbers
    doc = json.loads(board.read_text())
    doc["entries"][1]["sealed"][0]["final_error_deg"]["mean"] += 1.0
    board.write_text(json.dumps(doc))
    report = verify(board, Scoring(V1, runner=dask_runner))
    assert list(report.problems) == ["teacher"]


@pytest.mark.slow
def test_tuning_on_the_cluster_equals_the_serial_deferred_run(dask_runner: Runner, tmp_path: Path):
    class Serial:
        def __call__(self, fn, items):
            return list(map(fn, items))

    out = {}
    for label, runner in (("cluster", dask_runner), ("serial", Serial())):
        request = TrainRequest(
            controller="nussbaum", budget="quick", seed=2, out=tmp_path / f"{label}.yaml", runner=runner
        )
        tuning.tune(tuning.tune_spec("nussbaum", "scftc-v1"), request)
        out[label] = yaml.safe_load((tmp_path / f"{label}.yaml").read_text())["params"]
    assert out["cluster"] == out["serial"]


@pytest.mark.slow
def test_a_generation_spread_over_the_workers_equals_the_one_in_process(dask_runner: Runner, tmp_path: Path):
    spec = tuning.tune_spec("pid", "scftc-v3")
    assert spec.per_episode_params
    out = {}
    for label, runner in (("cluster", dask_runner), ("process", None)):
        request = TrainRequest(
            controller="pid",
            benchmark="scftc-v3",
            budget="quick",
            seed=4,
            out=tmp_path / f"{label}.yaml",
            runner=runner,
        )
        tuning.tune(spec, request)
        out[label] = yaml.safe_load((tmp_path / f"{label}.yaml").read_text())
    assert out["cluster"]["params"] == out["process"]["params"]
    assert (
        out["cluster"]["provenance"]["train_settled_rate"]
        == out["process"]["provenance"]["train_settled_rate"]
    )


@pytest.mark.slow
def test_the_study_on_the_cluster_measures_the_detector_and_draws_the_figures_as_in_process(
    dask_runner: Runner, monkeypatch, tmp_path
):
    """The detector is read off its own battery flight: in process, or on the workers that flew its
    stacks (chunk by chunk, joined in episode order). Both measure the same, number for number, and
    the figures drawn on the workers are the files drawn here, byte for byte."""
    from scftc_cli.study import run as study_run
    from scftc_cli.study.figures import write_figures
    from scftc_cli.versions import get_version
    from scftc_cli.versions.v2.spec import V2

    detector = get_version(V2.version).study.detector or ""
    only = {detector: registry(V2.version)[detector]}
    monkeypatch.setattr(study_run, "registry", lambda _benchmark=None: only)
    serial = study_run.run_study(V2, 1, 3)
    clustered = study_run.run_study(V2, 1, 3, runner=dask_runner)
    assert [d.fault_class for d in clustered.detection] == list(V2.fault_classes)
    for a, b in zip(serial.detection, clustered.detection, strict=True):
        for name in ("delay_steps", "faulted", "pre_onset_alarms", "healthy_alarms", "healthy_wheel_steps"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert len(clustered.trajectories) == len(V2.fault_classes)  # read off the workers' flights
    for a, b in zip(serial.trajectories, clustered.trajectories, strict=True):
        np.testing.assert_array_equal(a.error_deg, b.error_deg, err_msg=a.fault_class)
    here = write_figures(serial, tmp_path / "here")
    there = write_figures(clustered, tmp_path / "there", dask_runner)
    assert [p.name for p in here] == [p.name for p in there] and len(here) >= 10
    for a_path, b_path in zip(here, there, strict=True):
        assert a_path.read_bytes() == b_path.read_bytes(), a_path.name


def test_training_seeds_fly_on_the_cluster_to_the_serial_bits(dask_runner):
    """``reproduce --training-seeds`` spreads every seed's flight over the workers: a seed's weights
    travel as bytes and give the serial rates."""
    from scftc_cli.registry import controller_spec
    from scftc_cli.study.seeds import seed_spread

    entry = controller_spec("rma_dob")
    cells = [Cell("test", "gain_bias")]  # where v1's rma_dob seeds differ (docs/study.md section 3)
    serial = seed_spread(entry, V1, cells)
    spread = seed_spread(entry, V1, cells, runner=dask_runner)
    assert serial is not None and spread is not None and len(spread.rates) == 5
    assert len({tuple(rates) for rates in serial.rates.values()}) > 1  # the seeds' weights differ
    assert spread.rates == serial.rates and spread.pooled == serial.pooled
