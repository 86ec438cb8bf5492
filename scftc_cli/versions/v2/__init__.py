"""``scftc-v2``: the flight-like track (docs/benchmark-v2.md), one folder.

``spec.py`` holds its numbers, ``sim/`` its simulator (pinned draws, the reaction-wheel plant on
three backends, noisy redundant sensors), ``controllers/`` its battery, ``params/`` and
``weights/`` their tuned parameters and trained weights, ``training/`` the tuners and trainers that
made them (train split only), ``study.py`` its Basilisk cross-check plan and ``envs.py`` its
gymnasium environment. ``VERSION`` below is what the layers above ask of it
(``scftc_cli/versions/__init__.py``).
"""

from __future__ import annotations

from pathlib import Path

from scftc_cli.versions import TUNER, ControllerSpec, GymEnv, StudyPlan, Version
from scftc_cli.versions.v2.spec import V2

TUNED = ("pid", "classical_adaptive", "icl_adaptive", "nussbaum", "rls_dob")

REGIME_RULE = (
    "controllable: three star-tracker heads outvote one bad head, the gyro carries the attitude "
    "through an outage, and a gyro-bias step is observable through the heads: every sensor class "
    "can in principle be fought from the observation."
)

VERSION = Version(
    spec=V2,
    testbed="scftc_cli.versions.v2.sim.testbed:TESTBED",
    controllers=(
        ControllerSpec(
            "pd",
            "scftc_cli.versions.v2.controllers.analytic:PD",
            "fault-unaware PD + gyroscopic and friction feed-forwards, median of the star-tracker heads",
            family="reference",
        ),
        ControllerSpec(
            "pid",
            "scftc_cli.versions.v2.controllers.pid:PID",
            "PD + integral on the fused attitude with anti-windup, nominal allocation (fault-unaware)",
            artifacts=("params/v2/pid.yaml",),
            family="reference",
        ),
        ControllerSpec(
            "classical_adaptive",
            "scftc_cli.versions.v2.controllers.adaptive:ClassicalAdaptive",
            "per-wheel sign vote + gradient law for gain, offset and friction on the tachometer torque",
            artifacts=("params/v2/classical_adaptive.yaml",),
        ),
        ControllerSpec(
            "icl_adaptive",
            "scftc_cli.versions.v2.controllers.icl:ICLAdaptive",
            "per-wheel integral concurrent learning of (g, b, friction); stacks purged on a change",
            artifacts=("params/v2/icl_adaptive.yaml",),
        ),
        ControllerSpec(
            "nussbaum",
            "scftc_cli.versions.v2.controllers.nussbaum:Nussbaum",
            "per-wheel Nussbaum gain on the wheel-space error + adaptive offset term (no identification)",
            artifacts=("params/v2/nussbaum.yaml",),
        ),
        ControllerSpec(
            "rls_dob",
            "scftc_cli.versions.v2.controllers.rls:RLSDob",
            "per-wheel RLS on the tachometer torque + disturbance observer, latched, re-opened on a change",
            artifacts=("params/v2/rls_dob.yaml",),
        ),
        ControllerSpec(
            "e2e_ppo",
            "scftc_cli.versions.v2.controllers.ppo:E2EPPO",
            "end-to-end recurrent policy (LSTM) on the 19 raw readings, trained from scratch with PPO",
            artifacts=("weights/v2/e2e_ppo.npz",),
            family="learned",
        ),
        ControllerSpec(
            "rma_student",
            "scftc_cli.versions.v2.controllers.rma:RMAStudent",
            "RMA: per-wheel GRU estimate of g from the tachometer torque, latched, re-opened on a change",
            artifacts=("weights/v2/rma_student.npz",),
            family="learned",
        ),
        ControllerSpec(
            "rma_dob",
            "scftc_cli.versions.v2.controllers.rma:RMADob",
            "RMA bias-invariant gain student + per-wheel offset and friction observer",
            artifacts=("weights/v2/rma_dob.npz",),
            family="learned",
        ),
        ControllerSpec(
            "fdir",
            "scftc_cli.versions.v2.controllers.fdir:FDIR",
            "flight-style FDIR: MEKF with gyro-bias and head tests + per-wheel CUSUM and re-identification",
            artifacts=("params/v2/fdir.yaml",),
            family="classical",
        ),
        ControllerSpec(
            "teacher",
            "scftc_cli.versions.v2.controllers.analytic:Teacher",
            "privileged: the analytic law allocated through the true wheel effectiveness g(t)",
            privileged=True,
            family="oracle",
        ),
        ControllerSpec(
            "bias_oracle",
            "scftc_cli.versions.v2.controllers.analytic:BiasOracle",
            "privileged: the teacher plus the true wheel offsets and friction",
            privileged=True,
            family="oracle",
        ),
    ),
    folder=Path(__file__).resolve().parent,
    artifact_prefix="v2/",
    study=StudyPlan(
        sensors_in_battery=True,
        regime_rule=REGIME_RULE,
        detector="fdir",
        crosscheck="scftc_cli.versions.v2.study:CROSSCHECK",
    ),
    trainers={
        **dict.fromkeys(TUNED, TUNER),
        "rma_student": "scftc_cli.versions.v2.training.rma:train_student",
        "rma_dob": "scftc_cli.versions.v2.training.rma:train_student",
        "e2e_ppo": "scftc_cli.versions.v2.training.ppo:train_e2e_ppo",
        "fdir": "scftc_cli.versions.v2.training.fdir:tune_fdir",
    },
    tuning="scftc_cli.versions.v2.training.tuning:TUNING",
    envs=(
        GymEnv(
            "scftc/AttitudeFTC-v2",
            "scftc_cli.versions.v2.envs:AttitudeFTCv2Env",
            "scftc_cli.versions.v2.envs:AttitudeFTCv2VectorEnv",
        ),
    ),
    definition=("docs/benchmark-v2.md", "## 11. The spec as data"),
    alias="V2",
)
