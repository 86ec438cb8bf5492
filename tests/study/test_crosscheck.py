"""``scftc crosscheck``: scftc-v1's document unchanged, scftc-v2's groups, one-step map, saturation
counts and verdict, and the command's errors.

Tests that fly Basilisk are marked ``basilisk`` and skip where ``bsk`` is not installed; the rest
run everywhere (the one-step map and the saturation counts are checked on the numpy backends).
"""

from __future__ import annotations

import dataclasses
import json
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.evaluate import Cell
from scftc_cli.registry import make_controller
from scftc_cli.sim.rollout import rollout
from scftc_cli.study.crosscheck import (
    TOLERANCE,
    GroupCheck,
    crosscheck,
    default_controllers,
    plan,
    split_episodes,
    total_steps,
)
from scftc_cli.versions.v1.spec import V1
from scftc_cli.versions.v1.study import GROUPS
from scftc_cli.versions.v1.study import RigidCrosscheckResult as CrosscheckResult
from scftc_cli.versions.v2.sim.testbed import CONSTANTS, TESTBED
from scftc_cli.versions.v2.spec import V2
from scftc_cli.versions.v2.study import GROUPS as V2_GROUPS
from scftc_cli.versions.v2.study import (
    WheelCrosscheckResult,
    WheelGroupCheck,
    saturation,
    wheel_one_step_diff,
)

runner = CliRunner()
INSTALL_HINT = "pip install 'scftc[basilisk]'"
OMEGA_MAX = CONSTANTS.omega_max_rad_s


@pytest.fixture
def bsk():
    """The v2 Basilisk backend module; skips the test where ``bsk`` is not installed."""
    pytest.importorskip("Basilisk")
    from scftc_cli.versions.v2.sim import basilisk

    return basilisk


def _fly(name: str, fault_class: str, n: int = 3, backend: str = "numpy"):
    episodes = TESTBED.draw("test", fault_class, n_faults=n, n_seeds=1)
    return episodes, rollout(make_controller(name, V2.version), episodes, backend=backend, record=True)


# --- scftc-v1: the document is what it was ---------------------------------------------------


def test_v1_document_keeps_its_keys_and_order():
    group = GroupCheck("pd", GROUPS[0], 1, 1e-12, 2e-12, 3e-12, 4e-16, {"settled": 0}, {"numpy": 0})
    doc = CrosscheckResult(1, ("pd",), [group], {"numpy": 1.0}, "2.12.1").dump()
    assert list(doc) == [
        "benchmark_version", "episodes", "controllers", "rollouts", "steps", "max_abs_state_diff",
        "max_abs_sigma_diff", "max_abs_omega_diff_rad_s", "max_abs_command_diff", "max_abs_step_diff",
        "gates_agree", "tolerance", "passed", "basilisk_version", "seconds", "groups",
    ]  # fmt: skip
    assert list(doc["groups"][0]) == [
        "controller", "split", "class", "sensor", "n", "max_abs_sigma_diff", "max_abs_omega_diff_rad_s",
        "max_abs_command_diff", "max_abs_step_diff", "gate_disagreements", "settled_k",
    ]  # fmt: skip
    assert doc["benchmark_version"] == V1.version and doc["steps"] == V1.steps
    assert doc["max_abs_state_diff"] == 2e-12 and doc["passed"] is True
    assert default_controllers() == default_controllers(V1.version)
    assert total_steps(7, ("pd",)) == 2 * len(GROUPS) * V1.steps


# --- scftc-v2: what it flies -----------------------------------------------------------------


def test_v2_groups_cover_every_held_out_class_and_sensor_fault():
    assert plan(V2.version).groups == V2_GROUPS
    assert {c.split for c in V2_GROUPS} == {"test"}
    assert {c.fault_class for c in V2_GROUPS if c.sensor is None} == set(V2.fault_classes)
    assert {c.sensor for c in V2_GROUPS if c.sensor} == set(V2.sensor_faults)
    assert all(c.fault_class == V2.sensor_base_class for c in V2_GROUPS if c.sensor)
    # three episodes already fly a reversed wheel (sign), a friction fault and a dead wheel
    first = [c for c, k in zip(V2_GROUPS, split_episodes(3, len(V2_GROUPS)), strict=True) if k]
    assert first == [Cell("test", "sign"), Cell("test", "friction"), Cell("test", "loss")]


def test_v2_defaults_to_pd_and_the_teacher_and_counts_its_steps():
    assert default_controllers(V2.version) == ("pd", "teacher")
    assert total_steps(3, ("pd", "teacher"), V2.version) == 2 * 3 * 2 * V2.steps
    assert total_steps(20, ("pd",), V2.version) == 2 * len(V2_GROUPS) * V2.steps


def test_an_unknown_version_suggests_the_closest():
    with pytest.raises(UnknownNameError, match="scftc-v2"):
        plan("scftc-v22")


def test_a_version_without_a_cross_check_says_so(monkeypatch):
    from scftc_cli.study import crosscheck as module
    from scftc_cli.versions import get_version

    def without(name: str):
        version = get_version(name)
        return dataclasses.replace(version, study=dataclasses.replace(version.study, crosscheck=None))

    monkeypatch.setattr(module, "get_version", without)
    with pytest.raises(UsageError, match="no cross-check is defined for scftc-v2"):
        plan("scftc-v2")


# --- scftc-v2: the one-step map and the saturation counts ------------------------------------


@pytest.mark.parametrize("backend", ["numpy", "reference"])
@pytest.mark.parametrize("fault_class", ["friction", "gain_bias", "loss"])
def test_one_step_map_reproduces_the_numpy_plants_to_the_bit(fault_class: str, backend: str):
    # from each recorded state, the recorded command through the motor map (fault in force, clip,
    # speed cut) and one reference RK4 step give the next recorded state exactly
    episodes, run = _fly("pd", fault_class, backend=backend)
    assert wheel_one_step_diff(episodes, run) == 0.0


def test_one_step_map_sees_a_fault_switched_one_step_late():
    episodes, run = _fly("pd", "friction")
    late = dataclasses.replace(
        episodes, fault=dataclasses.replace(episodes.fault, onset_step=episodes.fault.onset_step + 1)
    )
    assert wheel_one_step_diff(late, run) > 1e-3


def test_pd_drives_reversed_wheels_into_the_speed_limit_and_the_teacher_does_not():
    episodes, run = _fly("pd", "sign")
    speeds = run.states["wheel_speed_rad_s"][:, :-1]
    saturated, cut = saturation(episodes, run)
    assert saturated == np.count_nonzero(np.any(np.abs(speeds) >= OMEGA_MAX, axis=2)) > 100
    assert 0 < cut <= saturated * CONSTANTS.n_wheels
    # the limit is what keeps the wheels near Omega_max: they overshoot it by at most one step
    assert np.abs(speeds).max() < OMEGA_MAX * 1.03
    episodes, run = _fly("teacher", "sign")
    assert saturation(episodes, run) == (0, 0)


def _wheel_group(**diffs: float) -> WheelGroupCheck:
    fields = {"max_abs_sigma_diff": 0.0, "max_abs_omega_diff": 0.0, "max_abs_wheel_speed_diff": 0.0} | diffs
    return WheelGroupCheck(
        controller="pd",
        cell=V2_GROUPS[0],
        n=1,
        max_abs_command_diff=0.0,
        max_abs_step_diff=0.0,
        gate_disagreements={"settled": 0},
        settled_k={"numpy": 0, "basilisk": 0},
        saturated_steps={"numpy": 5, "basilisk": 5},
        cut_wheel_steps={"numpy": 7, "basilisk": 7},
        **fields,
    )


def test_v2_verdict_holds_wheel_speeds_to_the_tolerance_as_a_fraction_of_omega_max():
    def result(group: WheelGroupCheck) -> WheelCrosscheckResult:
        return WheelCrosscheckResult(1, ("pd",), [group], {}, "2.12.1")

    within = result(_wheel_group(max_abs_wheel_speed_diff=100 * TOLERANCE))  # 1.6e-10 of Omega_max
    doc = within.dump()
    assert within.passed and doc["max_abs_state_diff"] == pytest.approx(100 * TOLERANCE / OMEGA_MAX)
    assert doc["max_abs_wheel_speed_diff_rad_s"] == 100 * TOLERANCE
    assert doc["saturated_steps"] == {"numpy": 5, "basilisk": 5} and doc["steps"] == V2.steps
    assert doc["groups"][0]["cut_wheel_steps"] == {"numpy": 7, "basilisk": 7}
    assert not result(_wheel_group(max_abs_wheel_speed_diff=2 * TOLERANCE * OMEGA_MAX)).passed
    assert not result(_wheel_group(max_abs_sigma_diff=2 * TOLERANCE)).passed
    assert not result(_wheel_group(max_abs_omega_diff=float("nan"))).passed


# --- the command -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--benchmark", "scftc-v22"], "scftc-v2"),
        (["--benchmark", "scftc-v2", "--controller", "rls_plan"], "scftc-v1 only"),
        (["--benchmark", "scftc-v2", "--controller", "teachr"], "teacher"),
    ],
)
def test_bad_usage_exits_2_with_one_clear_line(args: list[str], message: str):
    result = runner.invoke(app, ["crosscheck", "--episodes", "1", *args])
    assert result.exit_code == 2, result.output
    assert message in result.stderr and result.stdout == ""


def test_missing_basilisk_exits_1_with_an_install_hint(monkeypatch):
    for name in list(sys.modules):
        if name.split(".")[0] == "Basilisk" or name.startswith("scftc_cli.versions.v2.sim.basilisk"):
            monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "Basilisk", None)  # None in sys.modules: ImportError
    result = runner.invoke(app, ["crosscheck", "--benchmark", "scftc-v2", "--episodes", "1"])
    assert result.exit_code == 1
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and INSTALL_HINT in lines[0], result.stderr
    assert result.stdout == ""


# --- on Basilisk -----------------------------------------------------------------------------


@pytest.mark.basilisk
def test_v2_crosscheck_on_a_handful_of_episodes(bsk):
    result = crosscheck(3, ("pd", "teacher"), benchmark=V2.version)
    doc = result.dump()
    assert doc["benchmark_version"] == V2.version and doc["rollouts"] == 6
    assert [(g["controller"], g["class"]) for g in doc["groups"]] == [
        (name, c) for c in ("sign", "friction", "loss") for name in ("pd", "teacher")
    ]
    # measured (bsk 2.12.1): state 2.1e-13 (wheels 1.3e-10 rad/s), one step 1.1e-13 (1 ulp of 600 rad/s)
    assert result.passed and result.gates_agree
    assert result.max_abs_state_diff < 1e-11
    assert doc["max_abs_wheel_speed_diff_rad_s"] < 1e-8
    assert result.max_abs_step_diff < 1e-12
    # not vacuous: pd saturates wheels (the same steps on both), the teacher settles
    assert doc["saturated_steps"]["numpy"] == doc["saturated_steps"]["basilisk"] > 100
    assert doc["cut_wheel_steps"]["numpy"] == doc["cut_wheel_steps"]["basilisk"] > 100
    assert sum(g.settled_k["basilisk"] for g in result.groups if g.controller == "teacher") >= 2


@pytest.mark.basilisk
def test_v2_crosscheck_catches_a_command_applied_one_step_late(bsk, monkeypatch):
    # the hub before the wheel effector in the task: the documented trap (commands land late)
    monkeypatch.setattr(bsk, "WHEEL_PRIORITY", bsk.HUB_PRIORITY - 1)
    result = crosscheck(1, ("teacher",), benchmark=V2.version)
    assert result.max_abs_state_diff > 1e-6 and not result.passed


@pytest.mark.basilisk
def test_v2_crosscheck_command_prints_json_and_exits_0(bsk):
    args = ["crosscheck", "--benchmark", "scftc-v2", "--episodes", "2", "--controller", "teacher"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["benchmark_version"] == V2.version and doc["controllers"] == ["teacher"]
    assert doc["max_abs_state_diff"] < TOLERANCE and doc["gates_agree"] is True


@pytest.mark.slow
@pytest.mark.basilisk
def test_v2_crosscheck_passes_on_the_default_twenty_episodes(bsk):
    result = crosscheck(20, benchmark=V2.version)
    assert result.controllers == ("pd", "teacher") and result.passed
    assert result.max_abs_step_diff < 1e-12
    assert len(result.groups) == 2 * len(V2_GROUPS)
