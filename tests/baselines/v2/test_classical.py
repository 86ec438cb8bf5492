"""The ``scftc-v2`` classical ports that are tuned and registered: ``pid`` and ``nussbaum``
(``fdir`` has its own tests)."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
import yaml

from scftc_cli.baselines.checker import check_controller
from scftc_cli.baselines.params import v2_params_path
from scftc_cli.baselines.v2.nussbaum import Nussbaum, NussbaumParams
from scftc_cli.baselines.v2.pid import PID, PIDParams
from scftc_cli.registry import controller_spec
from scftc_cli.sim.rollout import rollout
from scftc_cli.sim.testbed import testbed as bed_for
from scftc_cli.sim.v2 import TESTBED
from scftc_cli.sim.v2.faults import WheelEpisodes, WheelFault
from scftc_cli.spec import V2
from scftc_cli.training import TrainRequest, get_trainer, tuning

BED = bed_for("scftc-v2")
NAMES = ("pid", "nussbaum")
DEFAULTS = {
    "pid": lambda: PID(PIDParams()),
    "nussbaum": lambda: Nussbaum(NussbaumParams()),
}


def with_fault(episodes: WheelEpisodes, **changes: np.ndarray) -> WheelEpisodes:
    """``episodes`` with fields of their fault replaced (every row alike where a 1-D row is given)."""
    fault = episodes.fault
    rows = {
        k: np.broadcast_to(np.asarray(v, float), getattr(fault, k).shape).copy() for k, v in changes.items()
    }
    if "onset_step" in rows:
        rows["onset_step"] = rows["onset_step"].astype(np.int64)
    return dataclasses.replace(episodes, fault=dataclasses.replace(fault, **rows))


# --- protocol and registration ----------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_every_port_passes_the_protocol_checker(name):
    check_controller(DEFAULTS[name](), benchmark="scftc-v2")


@pytest.mark.parametrize("name", NAMES)
def test_registered_for_v2_with_its_params_file_and_trainer(name):
    entry = controller_spec(name, "scftc-v2")
    assert entry.artifacts == (f"params/v2/{name}.yaml",)
    assert entry.artifact_paths()[0] == v2_params_path(name)
    assert entry.load().params_type is not None
    assert get_trainer(name, "scftc-v2").__module__ == "scftc_cli.training.tuning"
    assert name in tuning.V2_SPECS and tuning.V2_SPECS[name].benchmark == "scftc-v2"


@pytest.mark.parametrize("name", NAMES)
def test_committed_params_load_and_carry_their_provenance(name):
    path = v2_params_path(name)
    if not path.exists():
        pytest.skip(f"{path} not generated yet")
    doc = yaml.safe_load(path.read_text())
    assert doc["controller"] == name
    assert doc["provenance"]["benchmark_version"] == "scftc-v2"
    assert doc["provenance"]["budget"] == "full" and doc["provenance"]["seed"] == 0
    controller = controller_spec(name, "scftc-v2").make()
    check_controller(controller, benchmark="scftc-v2", steps=10, classes=("sign",))


def test_a_v2_port_refuses_v1():
    episodes = bed_for("scftc-v1").draw("train", "sign", n_faults=1, n_seeds=1)
    with pytest.raises(Exception, match="scftc-v2"):
        rollout(PID(PIDParams()), episodes, steps=2)


def test_pid_integrator_removes_a_gyro_bias_offset():
    episodes = BED.draw("train", "sign", "gyro_bias", n_faults=4, n_seeds=2)
    healthy = with_fault(episodes, gain=np.ones(4))
    pd_like = rollout(PID(PIDParams(ki_s3=1e-9)), healthy)
    pid = rollout(PID(PIDParams(ki_s3=5e-4, integrate_below=0.02)), healthy)
    assert np.median(pid.final_error_deg) < 0.5 * np.median(pd_like.final_error_deg)


def test_nussbaum_starts_as_the_nominal_law():
    """With ``N(zeta0) = 1`` and no error-driven adaptation yet, the first command is the
    nominal allocation of the analytic law (the pd calibration controller)."""
    from scftc_cli.baselines.v2.analytic import PD

    episodes = BED.draw("train", "sign", n_faults=2, n_seeds=2)
    ours = rollout(Nussbaum(NussbaumParams(gamma=0.0, gamma_d=0.0, k_null=0.0)), episodes, record=True)
    pd = rollout(PD(), episodes, record=True)
    np.testing.assert_allclose(ours.commands, pd.commands, atol=1e-9)


# --- tuning -----------------------------------------------------------------------------------------


def test_v2_tuning_samples_train_episodes_only_and_is_deterministic(tmp_path, monkeypatch):
    seen: list[WheelEpisodes] = []
    original = TESTBED.draw

    def recording(split, fault_class, *args, **kwargs):
        episodes = original(split, fault_class, *args, **kwargs)
        seen.append(episodes)
        return episodes

    monkeypatch.setattr(TESTBED, "draw", recording)  # every door to the episodes: tuning and scoring
    outputs = []
    for i in range(2):
        request = TrainRequest(
            controller="pid", benchmark="scftc-v2", seed=3, budget="quick", out=tmp_path / f"p{i}.yaml"
        )
        report = tuning.tune_pid(request)
        outputs.append(yaml.safe_load(report.artifact.read_text()))

    assert seen and {e.split for e in seen} == {"train"}
    train = V2.splits["train"]
    for episodes in seen:
        fault: WheelFault = episodes.fault
        assert np.all(train.onset_s.contains(fault.onset_step * V2.dt_s))
        assert np.all(train.inertia_scale.contains(fault.inertia_scale))
    assert outputs[0]["params"] == outputs[1]["params"]
    provenance = outputs[0]["provenance"]

    def timeless(p: dict) -> dict:  # the wall time and the creation date may differ, nothing else
        return {**p, "created_utc": None, "notes": re.sub(r"; wall \d+ s", "", p["notes"])}

    assert timeless(provenance) == timeless(outputs[1]["provenance"])
    assert provenance["benchmark_version"] == "scftc-v2" and provenance["budget"] == "quick"
    assert "sign+gyro_bias" in provenance["notes"]


def test_v1_tuning_is_untouched_by_the_v2_table():
    for name, spec in tuning.SPECS.items():
        assert spec.benchmark == "scftc-v1" and tuning.tune_spec(name) is spec
    assert tuning.tune_spec("nussbaum", "scftc-v2") is tuning.V2_SPECS["nussbaum"]
    assert tuning.Objective("nussbaum", 1, 1).benchmark == "scftc-v1"
    v1 = tuning.tuning_episodes(2, 1)
    assert v1.benchmark == "scftc-v1" and v1.fault_class == "sign+gain+gain_bias"
