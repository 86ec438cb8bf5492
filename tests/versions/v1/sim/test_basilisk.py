"""The Basilisk backend against the numpy backend, and the install hint when Basilisk is missing.

Tests that fly Basilisk are marked ``basilisk`` and skip where ``bsk`` is not installed; the
missing-backend test runs everywhere (it hides Basilisk from the import system).
"""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.study.crosscheck import TOLERANCE, crosscheck
from scftc_cli.versions.v1.sim.dynamics import rk4_step
from scftc_cli.versions.v1.spec import V1 as SPEC
from scftc_cli.versions.v1.study import GROUPS

INERTIA_NOMINAL = np.array(SPEC.plant.inertia_nominal_kgm2)

runner = CliRunner()
INSTALL_HINT = "pip install 'scftc[basilisk]'"


@pytest.fixture
def bsk():
    """The Basilisk backend module; skips the test where ``bsk`` is not installed."""
    pytest.importorskip("Basilisk")
    from scftc_cli.versions.v1.sim import basilisk

    return basilisk


@pytest.fixture
def without_basilisk(monkeypatch):
    """Make ``import Basilisk`` fail as it does where the optional extra is not installed."""
    for name in list(sys.modules):
        if name.split(".")[0] == "Basilisk" or name == "scftc_cli.versions.v1.sim.basilisk":
            monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "Basilisk", None)  # None in sys.modules: ImportError


@pytest.mark.basilisk
def test_one_step_matches_the_reference_including_the_shadow_switch(bsk):
    rng = np.random.default_rng(7)
    n = 6
    sigma0 = rng.uniform(-0.5, 0.5, (n, 3))
    # the last two start just inside |sigma| = 1, spinning outwards: they must switch in the step
    sigma0[-2:] = 0.999 * np.array([[1.0, 0.0, 0.0], [0.0, 0.6, 0.8]])
    omega0 = rng.uniform(-0.02, 0.02, (n, 3))
    omega0[-2:] = 0.4 * sigma0[-2:]
    inertia = rng.uniform(0.7, 2.3, (n, 1)) * INERTIA_NOMINAL
    torque = rng.uniform(-0.3, 0.3, (n, 3))
    # the actuator fault with g = 1, b = 0, tau_max = 1 applies the command as the torque, exactly
    plant = bsk.BasiliskPlant(
        sigma0, omega0, inertia, np.ones((n, 3)), np.zeros((n, 3)), 1.0, SPEC.plant.dt_s
    )
    plant.step(0, torque)
    sigma, omega = plant.sigma, plant.omega_rad_s
    ref_sigma, ref_omega = rk4_step(sigma0, omega0, torque, inertia, SPEC.plant.dt_s)
    # switched: back inside the unit sphere, pointing against where it was heading
    assert np.all(np.linalg.norm(sigma[-2:], axis=1) < 1.0)
    assert np.all(np.einsum("ij,ij->i", sigma[-2:], sigma0[-2:]) < 0), "Basilisk did not switch"
    np.testing.assert_allclose(sigma, ref_sigma, rtol=0, atol=1e-14)
    np.testing.assert_allclose(omega, ref_omega, rtol=0, atol=1e-14)


@pytest.mark.basilisk
def test_crosscheck_on_a_handful_of_episodes(bsk):
    result = crosscheck(len(GROUPS), ("pd", "bias_oracle"))
    doc = result.dump()
    assert doc["episodes"] == len(GROUPS) and doc["rollouts"] == 2 * len(GROUPS)
    assert {(g["class"], g["sensor"]) for g in doc["groups"]} == {(c.fault_class, c.sensor) for c in GROUPS}
    assert result.max_abs_state_diff < TOLERANCE
    assert result.max_abs_step_diff < 1e-13  # the same map, to rounding
    assert result.gates_agree and result.passed
    # not vacuous: the oracle settles some episodes, pd none, on both backends alike
    settled = {g.controller: g.settled_k["numpy"] for g in result.groups}
    assert sum(g.settled_k["basilisk"] for g in result.groups if g.controller == "bias_oracle") > 0
    assert settled["pd"] == 0


@pytest.mark.basilisk
def test_crosscheck_catches_a_command_applied_one_step_late(bsk, monkeypatch):
    # the hub before the effector in the task: the documented trap (commands land one step late)
    monkeypatch.setattr(bsk, "EFFECTOR_PRIORITY", bsk.HUB_PRIORITY - 1)
    result = crosscheck(2, ("bias_oracle",))
    assert result.max_abs_state_diff > 1e-6 and not result.passed


@pytest.mark.basilisk
def test_crosscheck_command_prints_json_and_exits_0(bsk):
    result = runner.invoke(app, ["crosscheck", "--episodes", "3", "--controller", "teacher"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["episodes"] == 3 and doc["controllers"] == ["teacher"]
    assert doc["max_abs_state_diff"] < TOLERANCE and doc["gates_agree"] is True


@pytest.mark.basilisk
def test_basilisk_eval_gives_the_numpy_k(bsk):
    args = [
        "--controller",
        "teacher",
        "--class",
        "sign",
        "--n-faults",
        "2",
        "--n-seeds",
        "2",
        "--format",
        "json",
    ]
    docs = {}
    for backend in ("numpy", "basilisk"):
        result = runner.invoke(app, ["eval", *args, "--backend", backend])
        assert result.exit_code == 0, result.output
        docs[backend] = json.loads(result.stdout)
    assert docs["basilisk"]["backend"] == "basilisk"
    (ref,), (bsk_cell,) = docs["numpy"]["cells"], docs["basilisk"]["cells"]
    for gate in ("settled", "operational", "touch_once"):
        assert bsk_cell[gate] == ref[gate]
    assert ref["settled"]["k"] == 4  # the teacher settles sign faults: the equality is not 0 == 0
    for stat in ("median", "mean"):
        assert bsk_cell["final_error_deg"][stat] == pytest.approx(ref["final_error_deg"][stat], abs=1e-9)


@pytest.mark.parametrize(
    "args",
    [
        [
            "eval",
            "--controller",
            "pd",
            "--class",
            "sign",
            "--n-faults",
            "1",
            "--n-seeds",
            "1",
            "--backend",
            "basilisk",
        ],
        ["crosscheck", "--episodes", "2"],
    ],
)
def test_missing_basilisk_exits_1_with_an_install_hint(without_basilisk, args):
    result = runner.invoke(app, args)
    assert result.exit_code == 1
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and INSTALL_HINT in lines[0], result.stderr
    assert result.stdout == ""


def test_numpy_backend_needs_no_basilisk(without_basilisk):
    args = [
        "eval",
        "--controller",
        "pd",
        "--class",
        "sign",
        "--n-faults",
        "1",
        "--n-seeds",
        "1",
        "--format",
        "json",
    ]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "Basilisk" not in sys.modules or sys.modules["Basilisk"] is None
