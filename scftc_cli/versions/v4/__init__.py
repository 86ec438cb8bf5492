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
        ControllerSpec(
            "fdir",
            "scftc_cli.versions.v4.controllers.fdir:FDIR",
            "composed FDIR: v2's MEKF (attitude, gyro bias, head isolation), rls_dob's per-wheel estimator "
            "and observer, v3 fdir's rod identification; detectors calibrated on healthy train flight",
            artifacts=("params/v4/fdir.yaml",),
            family="classical",
        ),
        ControllerSpec(
            "rma_student",
            "scftc_cli.versions.v4.controllers.rma:RMAStudent",
            "v3's rma_student (v2's per-wheel GRU estimate of g, latched, re-opened on a change) at the "
            "oracle's law gains, trained on v4's train split",
            artifacts=("weights/v4/rma_student.npz",),
            family="learned",
        ),
        ControllerSpec(
            "rma_dob",
            "scftc_cli.versions.v4.controllers.rma:RMADob",
            "v3's rma_dob (bias-invariant gain student + per-wheel offset and friction observer) at the "
            "oracle's law gains, trained on v4's train split",
            artifacts=("weights/v4/rma_dob.npz",),
            family="learned",
        ),
        ControllerSpec(
            "e2e_ppo",
            "scftc_cli.versions.v4.controllers.ppo:E2EPPO",
            "v3's end-to-end recurrent policy (LSTM) on the 26 readings, wheels and rods, PPO from scratch "
            "on v4's train split",
            artifacts=("weights/v4/e2e_ppo.npz",),
            family="learned",
        ),
        ControllerSpec(
            "residual_ppo",
            "scftc_cli.versions.v4.controllers.ppo:ResidualPPO",
            "pd's mission law plus a recurrent policy's correction (at most 0.2 of each actuator's "
            "limit), PPO on v4's train split",
            artifacts=("weights/v4/residual_ppo.npz",),
            family="learned",
        ),
        ControllerSpec(
            "teacher",
            "scftc_cli.versions.v4.controllers.analytic:Teacher",
            "privileged: v3's teacher (the law through the true g(t) and rod gains; perfect diagnosis) "
            "at the oracle's tuned gains",
            artifacts=("params/v4/oracle.yaml",),
            privileged=True,
            family="oracle",
        ),
        ControllerSpec(
            "oracle",
            "scftc_cli.versions.v4.controllers.analytic:Oracle",
            "privileged: v3's oracle (the teacher plus true offsets, friction, environment torques, "
            "true field) at its law gains tuned on v4's train split",
            artifacts=("params/v4/oracle.yaml",),
            privileged=True,
            family="oracle",
        ),
    ),
    folder=Path(__file__).resolve().parent,
    artifact_prefix="v4/",
    study=StudyPlan(
        sensors_in_battery=True,
        regime_rule=REGIME_RULE,
        detector=None,
        crosscheck="scftc_cli.versions.v4.study:CROSSCHECK",
    ),
    # every port's trainer; a port joins the controllers above once its committed parameters or
    # weights exist (as on v3)
    trainers={
        "pid": TUNER,
        "rls_dob": TUNER,
        "oracle": TUNER,
        "fdir": "scftc_cli.versions.v4.training.fdir:tune_fdir",
        "rma_student": "scftc_cli.versions.v4.training.rma:train_student",
        "rma_dob": "scftc_cli.versions.v4.training.rma:train_student",
        "e2e_ppo": "scftc_cli.versions.v4.training.ppo:train_e2e_ppo",
        "residual_ppo": "scftc_cli.versions.v4.training.ppo:train_residual_ppo",
    },
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
    in_training=(),
)
