"""A built-in controller flies a battery's cells stacked into one batch (``evaluate_stacked``):
that must give every cell exactly what flying it alone gives, for every built-in of every version,
or a table would depend on which cells were asked for together."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scftc_cli.errors import UsageError
from scftc_cli.evaluate import STACK_EPISODES, Cell, board_cells, evaluate_cell, evaluate_stacked, stacks
from scftc_cli.registry import make_controller, registry
from scftc_cli.sim.mrp import principal_angle_deg
from scftc_cli.sim.rollout import Rollout, rollout
from scftc_cli.sim.testbed import testbed as bed_for
from scftc_cli.spec import get_spec
from scftc_cli.versions import get_version, version_names

PAIRS = [(version, name) for version in version_names() for name in sorted(registry(version))]


def _cells(version: str) -> list[Cell]:
    """The version's board cells; a draft's on its train split (its held-out split stays closed to
    deployable controllers until its battery is frozen: ``evaluate.check_held_out_open``)."""
    cells = board_cells(get_spec(version))
    if get_version(version).draft:
        cells = [dataclasses.replace(c, split="train") for c in cells]
    return cells


def _some_cells(version: str) -> list[Cell]:
    """Three actuator cells (first, second, last) and two sensor cells (first, last)."""
    cells = _cells(version)
    actuator = [c for c in cells if c.sensor is None]
    sensor = [c for c in cells if c.sensor is not None]
    return [actuator[0], actuator[1], actuator[-1], sensor[0], sensor[-1]]


@pytest.mark.slow
@pytest.mark.parametrize(("version", "name"), PAIRS, ids=[f"{v}-{n}" for v, n in PAIRS])
def test_stacked_cells_score_bit_for_bit_as_cells_flown_alone(version: str, name: str) -> None:
    spec, cells = get_spec(version), _some_cells(version)
    make = lambda _cell: make_controller(name, version)  # noqa: E731
    alone = [evaluate_cell(make, spec, c, n_faults=2, n_seeds=2) for c in cells]
    stacked = evaluate_stacked(make, spec, cells, n_faults=2, n_seeds=2)
    for a, s in zip(alone, stacked, strict=True):
        assert s.cell == a.cell
        assert s.result == a.result
        for field in dataclasses.fields(a.outcomes):
            x, y = getattr(a.outcomes, field.name), getattr(s.outcomes, field.name)
            if isinstance(x, np.ndarray):
                np.testing.assert_array_equal(y, x, err_msg=f"{a.cell.label}: {field.name}")


@pytest.mark.parametrize("version", version_names())
def test_a_stack_keeps_each_cells_first_episode_as_its_recorded_flight_shows(version: str) -> None:
    """The trajectory figure reads each cell's first episode off the battery's stacked flight
    (``CellRun.trace``): the start's angle, then the error the plant scored after each step, as
    flying the cell alone with everything recorded shows it."""
    spec, bed, cells = get_spec(version), bed_for(version), _some_cells(version)
    stacked = evaluate_stacked(
        lambda _cell: make_controller("pd", version), spec, cells, n_faults=2, n_seeds=2
    )
    for cell, run in zip(cells, stacked, strict=True):
        episodes = bed.draw(cell.split, cell.fault_class, cell.sensor, 2, 2)
        flown = rollout(make_controller("pd", version), episodes, record=True)
        assert flown.error_deg is not None and run.trace is not None
        expected = np.concatenate([principal_angle_deg(flown.sigma[0, :1]), flown.error_deg[0]])
        np.testing.assert_array_equal(run.trace, expected, err_msg=cell.label)


def _arrays(flown: Rollout) -> dict[str, np.ndarray]:
    out = {}
    for field in dataclasses.fields(flown):
        value = getattr(flown, field.name)
        if isinstance(value, np.ndarray):
            out[field.name] = value
        elif dataclasses.is_dataclass(value):  # the health trace: its per-episode arrays (not its flags)
            inner = {f"{field.name}.{f.name}": getattr(value, f.name) for f in dataclasses.fields(value)}
            out |= {key: array for key, array in inner.items() if isinstance(array, np.ndarray)}
    return out


@pytest.mark.slow
def test_a_stack_large_enough_for_every_core_changes_no_bit() -> None:
    """The newest version's board cells at 300 episodes each: 5 100 rows, where the fused kernels
    run on all of numba's threads and the networks multiply large matrices. The first 60 steps of
    each built-in, stacked against each cell alone."""
    version = version_names()[-1]
    bed = bed_for(version)
    cells = _cells(version)
    parts = [bed.draw(c.split, c.fault_class, c.sensor, 30, 10) for c in cells]
    whole = type(parts[0]).concat(parts)
    assert whole.n >= 5_000
    for name in sorted(registry(version)):
        alone = [_arrays(rollout(make_controller(name, version), p, steps=60)) for p in parts]
        stacked = _arrays(rollout(make_controller(name, version), whole, steps=60))
        for key, value in stacked.items():
            joined = np.concatenate([a[key] for a in alone])
            np.testing.assert_array_equal(value, joined, err_msg=f"{name}: {key}")


def test_stacks_keep_order_bound_size_and_respect_cell_wide_sensor_faults() -> None:
    cells = board_cells(get_spec("scftc-v2"))
    n = 500
    groups = stacks(get_spec("scftc-v2"), cells, n)
    assert [i for g in groups for i in g] == list(range(len(cells)))
    assert all(len(g) * n <= STACK_EPISODES for g in groups)
    assert len(groups) == -(-len(cells) * n // STACK_EPISODES)
    v1 = get_spec("scftc-v1")
    v1_cells = board_cells(v1)
    for group in stacks(v1, v1_cells, 4):
        assert len({v1_cells[i].sensor for i in group}) == 1  # v1's sensors hold one cell's fault


def test_a_cluster_flies_a_built_in_as_one_stack_per_worker_and_a_submission_in_turn() -> None:
    from scftc_cli.distributed.refs import BuiltinRef, SubmissionRef
    from scftc_cli.evaluate import cluster_tasks

    spec = get_spec("scftc-v2")
    cells = board_cells(spec)
    built_in = cluster_tasks(BuiltinRef("pd", spec.version), spec, cells, workers=2)
    assert [len(t.parts) for t in built_in] == [-(-len(cells) // 2), len(cells) // 2]
    assert [p.fault_class for t in built_in for p in t.parts] == [c.fault_class for c in cells]
    submitted = cluster_tasks(SubmissionRef("x.py", b"SUBMISSION = {}"), spec, cells, workers=2)
    assert [len(t.parts) for t in submitted] == [-(-len(cells) // 2), len(cells) // 2]
    assert all(t.in_turn for t in submitted) and not any(t.in_turn for t in built_in)
    assert [p.fault_class for t in submitted for p in t.parts] == [c.fault_class for c in cells]


@pytest.mark.parametrize("version", version_names())
def test_draws_with_their_own_salts_stack_as_each_draw_flown_alone(version: str) -> None:
    """A board's public and sealed draws of the same cells fly as one batch (``salts``): each cell
    scores as its draw flown alone, and the two draws really differ."""
    spec, cells = get_spec(version), _some_cells(version)
    make = lambda _cell: make_controller("pd", version)  # noqa: E731
    salts = [b"", b"sealed"]
    both = evaluate_stacked(
        make, spec, cells * 2, n_faults=2, n_seeds=2, salts=[s for s in salts for _ in cells]
    )
    for i, salt in enumerate(salts):
        alone = evaluate_stacked(make, spec, cells, n_faults=2, n_seeds=2, salt=salt)
        for a, s in zip(alone, both[i * len(cells) : (i + 1) * len(cells)], strict=True):
            assert s.result == a.result
            np.testing.assert_array_equal(s.outcomes.final_error_deg, a.outcomes.final_error_deg)
    assert not np.array_equal(both[0].outcomes.final_error_deg, both[len(cells)].outcomes.final_error_deg)
    with pytest.raises(UsageError, match="1 salts for 5 cells"):
        evaluate_stacked(make, spec, cells, n_faults=1, n_seeds=1, salts=[b""])
