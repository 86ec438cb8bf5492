"""``scftc-v4``: the agile track recalibrated (docs/benchmark-v4.md), one folder.

``spec.py`` holds its numbers (v3's plant, sensors and mission by import; its own fault classes,
admission rule and diagnosis ranking), ``sim/`` its draws and testbed (v3's simulator on v4's
draws), ``controllers/`` the ports whose settings are v4's own. ``VERSION`` below is what the
layers above ask of it (``scftc_cli/versions/__init__.py``).
"""

from __future__ import annotations

from pathlib import Path

from scftc_cli.versions import TUNER, ControllerSpec, GymEnv, StudyPlan, Version
from scftc_cli.versions.v3 import REGIME_RULE
from scftc_cli.versions.v3 import VERSION as V3_VERSION
from scftc_cli.versions.v4.spec import V4

V3_BUILT_INS = {entry.name: entry for entry in V3_VERSION.controllers}
"""v3's built-ins; v4 flies its calibration controllers as they are (``Version`` binds them to v4)."""

VERSION = Version(
    spec=V4,
    testbed="scftc_cli.versions.v4.sim.testbed:TESTBED",
    controllers=(
        V3_BUILT_INS["pd"],
        ControllerSpec(
            "pid",
            "scftc_cli.versions.v4.controllers.pid:PID",
            "v3's pid (PD + clamped integral on the mission law, fault-unaware), tuned on v4's train split",
            artifacts=("params/v4/pid.yaml",),
            family="reference",
        ),
        ControllerSpec(
            "rls_dob",
            "scftc_cli.versions.v4.controllers.rls:RLSDob",
            "v3's rls_dob (v2's per-wheel RLS + disturbance observer on the mission law), tuned on v4's "
            "train split from v3's settings",
            artifacts=("params/v4/rls_dob.yaml",),
        ),
        V3_BUILT_INS["teacher"],
        V3_BUILT_INS["oracle"],
    ),
    folder=Path(__file__).resolve().parent,
    artifact_prefix="v4/",
    study=StudyPlan(sensors_in_battery=True, regime_rule=REGIME_RULE, detector=None),
    trainers={"pid": TUNER, "rls_dob": TUNER},
    tuning="scftc_cli.versions.v4.training.tuning:TUNING",
    envs=(
        GymEnv(
            "scftc/AttitudeFTC-v4",
            "scftc_cli.versions.v4.envs:AttitudeFTCv4Env",
            "scftc_cli.versions.v4.envs:AttitudeFTCv4VectorEnv",
        ),
    ),
    definition=("docs/benchmark-v4.md", "## 9. The spec as data"),
    alias="V4",
    draft=True,
)
