"""``scftc-v3``: the agile track (docs/benchmark-v3.md), one folder.

``spec.py`` holds its numbers, ``sim/`` its simulator (seeded draws of faults, orbits and missions;
the plant in orbit on three backends; v2's sensors plus a magnetometer; the mission's windows and
the diagnosis truth), ``controllers/`` its calibration battery. ``VERSION`` below is what the
layers above ask of it (``scftc_cli/versions/__init__.py``). Published: its board is
``leaderboard/scftc-v3.json``, and every number here is part of the version.
"""

from __future__ import annotations

from pathlib import Path

from scftc_cli.versions import TUNER, ControllerSpec, GymEnv, StudyPlan, Version
from scftc_cli.versions.v3.spec import V3

REGIME_RULE = (
    "controllable: v2's heads, gyro and tachometers, plus a magnetometer whose bias does not move the "
    "pointing (it misleads the unloading and the rods' feed-forward): every sensor class can in "
    "principle be fought from the observation."
)

VERSION = Version(
    spec=V3,
    testbed="scftc_cli.versions.v3.sim.testbed:TESTBED",
    controllers=(
        ControllerSpec(
            "pd",
            "scftc_cli.versions.v3.controllers.analytic:PD",
            "fault-unaware rate-limited PD to the window's target, rods unloading by h x B, "
            "rod torque fed forward",
            family="reference",
        ),
        ControllerSpec(
            "pid",
            "scftc_cli.versions.v3.controllers.pid:PID",
            "PD + integral on the fused attitude with anti-windup on the mission law, nominal allocation "
            "(fault-unaware), rods unloading as in pd",
            artifacts=("params/v3/pid.yaml",),
            family="reference",
        ),
        ControllerSpec(
            "rls_dob",
            "scftc_cli.versions.v3.controllers.rls:RLSDob",
            "v2's per-wheel RLS on the tachometer torque + disturbance observer, latched, re-opened on a "
            "change, on the mission law",
            artifacts=("params/v3/rls_dob.yaml",),
        ),
        ControllerSpec(
            "rma_student",
            "scftc_cli.versions.v3.controllers.rma:RMAStudent",
            "RMA: v2's per-wheel GRU estimate of g on the mission law, latched, re-opened on a change",
            artifacts=("weights/v3/rma_student.npz",),
            family="learned",
        ),
        ControllerSpec(
            "e2e_ppo",
            "scftc_cli.versions.v3.controllers.ppo:E2EPPO",
            "end-to-end recurrent policy (LSTM) on the 26 readings, wheels and rods, PPO from scratch",
            artifacts=("weights/v3/e2e_ppo.npz",),
            family="learned",
        ),
        ControllerSpec(
            "rma_dob",
            "scftc_cli.versions.v3.controllers.rma:RMADob",
            "RMA bias-invariant gain student + per-wheel offset and friction observer, mission law",
            artifacts=("weights/v3/rma_dob.npz",),
            family="learned",
        ),
        ControllerSpec(
            "fdir",
            "scftc_cli.versions.v3.controllers.fdir:FDIR",
            "residual FDIR: per-wheel torque residuals and gain identification, rod-gain identification, "
            "head votes, magnetometer spikes; reports its diagnosis and reconfigures",
            family="classical",
        ),
        ControllerSpec(
            "teacher",
            "scftc_cli.versions.v3.controllers.analytic:Teacher",
            "privileged: the law through the true g(t) and rod gains; perfect diagnosis",
            privileged=True,
            family="oracle",
        ),
        ControllerSpec(
            "oracle",
            "scftc_cli.versions.v3.controllers.analytic:Oracle",
            "privileged: the teacher plus true offsets, friction (bursts, ramps), environment torques, "
            "true field",
            privileged=True,
            family="oracle",
        ),
    ),
    folder=Path(__file__).resolve().parent,
    artifact_prefix="v3/",
    study=StudyPlan(
        sensors_in_battery=True,
        regime_rule=REGIME_RULE,
        detector=None,
        crosscheck="scftc_cli.versions.v3.study:CROSSCHECK",
    ),
    # every port's trainer; a port joins the controllers above once its committed parameters or
    # weights exist (docs/benchmark-v3.md, section 11): `scftc train` asks for a listed controller
    trainers={
        "pid": TUNER,
        "rls_dob": TUNER,
        "rma_student": "scftc_cli.versions.v3.training.rma:train_student",
        "rma_dob": "scftc_cli.versions.v3.training.rma:train_student",
        "e2e_ppo": "scftc_cli.versions.v3.training.ppo:train_e2e_ppo",
    },
    tuning="scftc_cli.versions.v3.training.tuning:TUNING",
    envs=(
        GymEnv(
            "scftc/AttitudeFTC-v3",
            "scftc_cli.versions.v3.envs:AttitudeFTCv3Env",
            "scftc_cli.versions.v3.envs:AttitudeFTCv3VectorEnv",
        ),
    ),
    definition=("docs/benchmark-v3.md", "## 9. The spec as data"),
    alias="V3",
    superseded_by="scftc-v4",
)
