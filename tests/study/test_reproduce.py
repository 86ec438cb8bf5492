"""``scftc reproduce`` on a reduced size: every file written, the JSON equal to ``scftc eval``'s,
real images, the sensor regime rule, and the sensor-bias floor on the true attitude."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.evaluate import evaluate_stacked, select_cells
from scftc_cli.protocol import Controller, Progress
from scftc_cli.records import CellResult, EvalResult, FinalError, GateStat
from scftc_cli.registry import ControllerSpec, make_controller, registry
from scftc_cli.sim.rollout import rollout
from scftc_cli.statistics import PROFILE_TAUS_DEG
from scftc_cli.study import run as study_run
from scftc_cli.study.figures import FIGURES
from scftc_cli.study.run import (
    StudyError,
    choose_deployed,
    planned_steps,
    run_study,
    sensor_bias_deg,
    sensor_regime,
)
from scftc_cli.versions.v1.sim.testbed import TESTBED
from scftc_cli.versions.v1.spec import V1 as SPEC

runner = CliRunner()
N_FAULTS, N_SEEDS = 2, 2
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
TABLES = (
    "battery.md",
    "battery.json",
    "sensor.md",
    "sensor.json",
    "gate_sensitivity.md",
    "final_error_profile.md",
    "settling_time.md",
    "distributions.json",
)


@pytest.fixture(scope="module")
def study_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("results")
    args = ["reproduce", "--out", str(out), "--n-faults", str(N_FAULTS), "--n-seeds", str(N_SEEDS)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    return out


@pytest.mark.slow
def test_settled_by_hub_splits_each_controllers_battery_episodes_between_the_held_out_hub_parts(
    study_dir: Path,
) -> None:
    battery = {r["controller"]: r for r in json.loads((study_dir / "battery.json").read_text())["results"]}
    rows = [
        line.split(" | ")
        for line in (study_dir / "settled_by_hub.md").read_text().splitlines()[-len(battery) :]
    ]
    assert len(rows[0]) == 3  # controller and the two held-out parts (lighter, heavier than train)
    for row in rows:
        name = row[0].strip("| ").removesuffix(" (privileged)")
        n = [int(cell.rsplit("(n = ", 1)[1].rstrip(") |")) for cell in row[1:]]
        rates = [float(cell.split()[0]) if not cell.startswith("-") else 0.0 for cell in row[1:]]
        cells = [c for c in battery[name]["cells"] if c["sensor"] is None]
        assert sum(n) == sum(c["n"] for c in cells)
        settled = sum(c["settled"]["k"] for c in cells)
        assert sum(round(r * k / 100) for r, k in zip(rates, n, strict=True)) == settled


def _eval_json(*args: str) -> dict:
    sizes = ("--n-faults", str(N_FAULTS), "--n-seeds", str(N_SEEDS), "--format", "json")
    result = runner.invoke(app, ["eval", *args, *sizes])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


@pytest.mark.slow
def test_writes_every_table_and_figure(study_dir: Path) -> None:
    expected = set(TABLES) | {f"{stem}.{ext}" for stem in FIGURES for ext in ("png", "svg")}
    assert expected <= {p.name for p in study_dir.iterdir()}
    for name in expected:
        assert (study_dir / name).stat().st_size > 0, name


@pytest.mark.slow
def test_battery_json_is_what_eval_prints_for_every_registered_controller(study_dir: Path) -> None:
    doc = json.loads((study_dir / "battery.json").read_text())
    names = [r["controller"] for r in doc["results"]]
    assert names == list(registry())  # nobody silently missing, in battery order
    assert (doc["n_faults"], doc["n_seeds"]) == (N_FAULTS, N_SEEDS)
    for result in doc["results"]:
        assert [c["class"] for c in result["cells"]] == list(SPEC.fault_classes)
        assert result == _eval_json("--controller", result["controller"])


@pytest.mark.slow
def test_sensor_json_is_what_eval_prints_and_holds_the_teacher(study_dir: Path) -> None:
    doc = json.loads((study_dir / "sensor.json").read_text())
    names = [r["controller"] for r in doc["results"]]
    assert "teacher" in names and doc["deployed"] in names
    assert not next(r for r in doc["results"] if r["controller"] == doc["deployed"])["privileged"]
    assert doc["regimes"] == {s: sensor_regime(SPEC, s, SPEC.gates.settled_deg) for s in SPEC.sensor_faults}
    for result in doc["results"]:
        assert [c["sensor"] for c in result["cells"]] == list(SPEC.sensor_faults)
        assert result == _eval_json("--controller", result["controller"], "--sensor", "all")


@pytest.mark.slow
def test_markdown_tables_hold_every_cell(study_dir: Path) -> None:
    battery_md = (study_dir / "battery.md").read_text()
    n_controllers = len(registry())
    k_over_n = f"/{N_FAULTS * N_SEEDS} |"
    assert battery_md.count(k_over_n) == n_controllers * len(SPEC.fault_classes)
    assert all(name in battery_md for name in registry())
    sensor_md = (study_dir / "sensor.md").read_text()
    n_sensor = len(json.loads((study_dir / "sensor.json").read_text())["results"])
    assert sensor_md.count(k_over_n) == n_sensor * len(SPEC.sensor_faults)
    assert "shield-only" in sensor_md and "controllable" in sensor_md


@pytest.mark.slow
@pytest.mark.parametrize("stem", FIGURES)
def test_every_png_is_a_real_image_of_some_size(study_dir: Path, stem: str) -> None:
    png = study_dir / f"{stem}.png"
    assert png.read_bytes()[:8] == PNG_SIGNATURE
    assert png.stat().st_size > 20_000  # a blank or broken canvas compresses to a few KB
    height, width = matplotlib.image.imread(png).shape[:2]
    assert height >= 400 and width >= 600
    svg = (study_dir / f"{stem}.svg").read_text()
    assert "<svg" in svg and "</svg>" in svg


@pytest.mark.slow
def test_distributions_agree_with_the_battery_and_the_sensor_table(study_dir: Path) -> None:
    """distributions.json holds, per controller and cell, the counts the new tables and figures
    are drawn from: at the benchmark's own gate they are the battery's settled counts, the profile
    never decreases and reaches every episode at 180 deg."""
    doc = json.loads((study_dir / "distributions.json").read_text())
    at_gate = doc["gates_deg"].index(SPEC.gates.settled_deg)
    assert doc["taus_deg"] == pytest.approx(PROFILE_TAUS_DEG.tolist())
    settled = {}
    for name in ("battery.json", "sensor.json"):
        for r in json.loads((study_dir / name).read_text())["results"]:
            for c in r["cells"]:
                settled[(r["controller"], c["sensor"] or c["class"])] = c["settled"]["k"]
    assert {(c["controller"], c["cell"]) for c in doc["cells"]} == set(settled)
    for cell in doc["cells"]:
        assert cell["settled_at_gates"][at_gate] == settled[(cell["controller"], cell["cell"])]
        assert cell["settled_at_gates"] == sorted(cell["settled_at_gates"])
        profile = cell["final_error_profile"]
        assert profile == sorted(profile) and profile[-1] == cell["n"] == N_FAULTS * N_SEEDS
    sensitivity = (study_dir / "gate_sensitivity.md").read_text()
    assert sensitivity.count("## ") == len(SPEC.fault_classes) + len(SPEC.sensor_faults)


def test_regime_rule_follows_the_gate() -> None:
    assert [sensor_regime(SPEC, s, SPEC.gates.settled_deg) for s in SPEC.sensor_faults] == [
        "controllable",  # bias_0.1: 0.1 deg < 0.2 deg gate
        "shield-only",  # bias_0.2: the truth parks on the gate itself
        "shield-only",
        "shield-only",
        "shield-only",  # dropout: no attitude measured
        "shield-only",  # stuck: likewise
    ]
    assert sensor_regime(SPEC, "bias_0.3", gate_deg=0.4) == "controllable"
    assert sensor_bias_deg(SPEC, "bias_0.5") == 0.5 and sensor_bias_deg(SPEC, "dropout") is None


@pytest.mark.parametrize("sensor", ["bias_0.3", "bias_0.5"])
def test_sensor_bias_leaves_the_true_attitude_off_by_the_bias(sensor: str) -> None:
    """The teacher regulates the *measured* attitude to zero; an unobservable constant offset
    leaves the true one parked at the bias, above the gate."""
    episodes = TESTBED.draw("test", "sign", sensor, n_faults=5, n_seeds=2)
    final_deg = rollout(make_controller("teacher"), episodes).final_error_deg
    bias_deg = sensor_bias_deg(SPEC, sensor)
    assert np.all(np.abs(final_deg - bias_deg) < 0.05), final_deg
    assert np.all(final_deg > SPEC.gates.settled_deg)


@pytest.mark.slow
def test_sensor_json_teacher_parks_at_the_bias(study_dir: Path) -> None:
    doc = json.loads((study_dir / "sensor.json").read_text())
    teacher = next(r for r in doc["results"] if r["controller"] == "teacher")
    for cell in teacher["cells"]:
        bias = sensor_bias_deg(SPEC, cell["sensor"])
        if bias is not None and bias >= 0.3:
            assert abs(cell["final_error_deg"]["median"] - bias) < 0.05
            assert cell["settled"]["k"] == 0


def _result(name: str, privileged: bool, rates: dict[str, float]) -> EvalResult:
    def cell(fault_class: str, rate: float) -> CellResult:
        stat = GateStat(k=round(10 * rate), rate=rate, ci_low=0.0, ci_high=1.0)
        return CellResult(
            split="test",
            fault_class=fault_class,
            sensor=None,
            n=10,
            settled=stat,
            operational=stat,
            touch_once=stat,
            final_error_deg=FinalError(median=1.0, mean=1.0),
        )

    cells = [cell(c, rates.get(c, 0.0)) for c in SPEC.fault_classes]
    return EvalResult(
        benchmark_version=SPEC.version, controller=name, privileged=privileged, backend="numpy", cells=cells
    )


def test_deployed_choice_prefers_rma_dob_then_the_best_deployable() -> None:
    teacher = _result("teacher", True, {"sign": 1.0, "gain": 1.0})
    weak = _result("pd", False, {})
    strong = _result("rls_dob", False, {"sign": 0.9, "gain": 0.8})
    rma_dob = _result("rma_dob", False, {"sign": 0.5, "gain": 0.5})
    assert choose_deployed([weak, strong, teacher], "rma_dob")[0] == "rls_dob"  # never the oracle
    assert choose_deployed([weak, strong, rma_dob, teacher], "rma_dob")[0] == "rma_dob"
    assert choose_deployed([teacher], "rma_dob")[0] is None


class _Broken(Controller):
    def __init__(self) -> None:
        raise FileNotFoundError("weights/broken.pt is not there")

    def reset(self, n, context) -> None:  # pragma: no cover
        pass

    def act(self, obs):  # pragma: no cover
        return obs[:, :3]


def test_a_controller_that_fails_to_load_stops_the_study(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    broken = {"broken": ControllerSpec("broken", f"{__name__}:_Broken", "cannot load")}
    monkeypatch.setattr(study_run, "registry", lambda _benchmark=None: broken)
    with pytest.raises(StudyError, match="failed to load: `broken` .FileNotFoundError"):
        run_study(SPEC, 1, 1)
    result = runner.invoke(
        app, ["reproduce", "--out", str(tmp_path / "out"), "--n-faults", "1", "--n-seeds", "1"]
    )
    assert result.exit_code == 1 and not (tmp_path / "out").exists()
    assert "broken" in result.stderr


class _Counting(Progress):
    def __init__(self) -> None:
        self.steps, self.descriptions = 0, []

    def advance(self, amount: float = 1.0) -> None:
        self.steps += amount

    def describe(self, text: str) -> None:
        self.descriptions.append(text)


@pytest.mark.slow
def test_progress_total_is_the_work_done() -> None:
    progress = _Counting()
    run_study(SPEC, 1, 1, progress=progress)
    assert progress.steps == planned_steps(SPEC)


def test_example_trajectories_on_v3_plot_the_error_to_each_windows_target() -> None:
    """scftc-v3's hub scale is a mass property of the episode and its error is to the current
    window's target: the trajectory is the error the plant scored, from the first target (the
    origin) on; a slew's new target shows as a jump at the window's start."""
    from scftc_cli.spec import get_spec

    spec = get_spec("scftc-v3")
    narrow = spec.model_copy(update={"classes": tuple(c for c in spec.classes if c.name == "nominal")})
    pd = registry("scftc-v3")["pd"]
    cells = select_cells(narrow, "test", None, None)
    runs = evaluate_stacked(lambda _cell: pd.make(), narrow, cells, n_faults=1, n_seeds=2)
    (trajectory,) = study_run.example_trajectories([pd], narrow, {"pd": runs})
    assert trajectory.error_deg.shape == (spec.steps + 1,) and 0.5 < trajectory.inertia_scale < 2.0
    window = spec.plant.window_steps
    assert trajectory.error_deg[window + 1] > 10 * trajectory.error_deg[window]  # the slew to target 2
    assert trajectory.error_deg[window] < 0.2 and trajectory.error_deg[-1] < 0.2  # settled on both


def test_the_hub_inertia_scale_is_read_wherever_a_version_keeps_it() -> None:
    """v1 and v2 keep the hub's scale on the fault, v3 on the episode (a mass property): the
    settled-by-hub table and the trajectories read both (v3's reproduce once failed on it)."""
    from scftc_cli.sim.testbed import testbed

    for version in ("scftc-v1", "scftc-v2", "scftc-v3"):
        episodes = testbed(version).draw("test", "gain", n_faults=3, n_seeds=1)
        kept = getattr(episodes.fault, "inertia_scale", None)
        expected = episodes.inertia_scale if kept is None else kept
        np.testing.assert_array_equal(study_run.inertia_scale(episodes), expected)
        assert study_run.inertia_scale(episodes).shape == (3,)
