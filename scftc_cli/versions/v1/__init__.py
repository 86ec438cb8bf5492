"""``scftc-v1``: the source study's testbed (docs/benchmark.md), one folder.

``spec.py`` holds its numbers, ``sim/`` its simulator (pinned draws, plant on three backends,
sensors), ``controllers/`` its battery, ``params/`` and ``weights/`` their tuned parameters and
trained weights, ``training/`` the tuners and trainers that made them (train split only),
``study.py`` its Basilisk cross-check plan and ``envs.py`` its gymnasium environment. ``VERSION``
below is what the layers above ask of it (``scftc_cli/versions/__init__.py``).
"""

from __future__ import annotations

from pathlib import Path

from scftc_cli.versions import TUNER, ControllerSpec, GymEnv, StudyPlan, Version
from scftc_cli.versions.v1.spec import V1

TUNED = ("pid", "classical_adaptive", "icl_adaptive", "nussbaum", "rls_dob", "rls_plan")

REGIME_RULE = (
    "controllable: the star tracker reports the true attitude offset by a constant rotation strictly "
    "smaller than the settled gate, so driving the measured attitude to zero also settles the true one; "
    "shield-only: the offset is at or above the gate (a constant bias is unobservable from "
    "[sigma_meas, w], so the truth parks at the bias: at exactly the gate, rounding decides) or the "
    "attitude is not measured at all (dropout, stuck) - only an independent reference or a safety "
    "shield can help."
)

VERSION = Version(
    spec=V1,
    testbed="scftc_cli.versions.v1.sim.testbed:TESTBED",
    controllers=(
        ControllerSpec(
            "pd",
            "scftc_cli.versions.v1.controllers.analytic:PD",
            "fault-unaware inertia-scaled PD on MRPs",
            family="reference",
        ),
        ControllerSpec(
            "pid",
            "scftc_cli.versions.v1.controllers.pid:PID",
            "PD + integral on sigma with conditional-integration and clamping anti-windup",
            artifacts=("params/pid.yaml",),
            family="reference",
        ),
        ControllerSpec(
            "classical_adaptive",
            "scftc_cli.versions.v1.controllers.adaptive:ClassicalAdaptive",
            "per-axis sign identification (vote) + adaptive gain magnitude and bias",
            artifacts=("params/classical_adaptive.yaml",),
        ),
        ControllerSpec(
            "icl_adaptive",
            "scftc_cli.versions.v1.controllers.icl:ICLAdaptive",
            "integral concurrent learning of (theta, beta) with a history stack (Parikh 2019)",
            artifacts=("params/icl_adaptive.yaml",),
        ),
        ControllerSpec(
            "nussbaum",
            "scftc_cli.versions.v1.controllers.nussbaum:Nussbaum",
            "per-axis Nussbaum gain for unknown direction + adaptive bias term (Nussbaum 1983)",
            artifacts=("params/nussbaum.yaml",),
        ),
        ControllerSpec(
            "e2e_ppo",
            "scftc_cli.versions.v1.controllers.ppo:E2EPPO",
            "end-to-end recurrent policy (LSTM) trained from scratch with PPO",
            artifacts=("weights/e2e_ppo.npz",),
            family="learned",
        ),
        ControllerSpec(
            "rma_student",
            "scftc_cli.versions.v1.controllers.rma:RMAStudent",
            "RMA: latched GRU estimate of theta = g/f feeding the analytic law",
            artifacts=("weights/rma_student.npz",),
            family="learned",
        ),
        ControllerSpec(
            "rma_dob",
            "scftc_cli.versions.v1.controllers.rma:RMADob",
            "RMA gain student (trained with biases) + disturbance observer",
            artifacts=("weights/rma_dob.npz",),
            family="learned",
        ),
        ControllerSpec(
            "rls_dob",
            "scftc_cli.versions.v1.controllers.rls:RLSDob",
            "per-axis RLS on the measured torque + disturbance observer, latched (no learning)",
            artifacts=("params/rls_dob.yaml",),
        ),
        ControllerSpec(
            "rls_plan",
            "scftc_cli.versions.v1.controllers.plan:RLSPlan",
            "rls_dob + dead-axis plan (gyroscopic rate nulling, p-q-p slews) + low-margin bias plan",
            artifacts=("params/rls_plan.yaml",),
        ),
        ControllerSpec(
            "teacher",
            "scftc_cli.versions.v1.controllers.analytic:Teacher",
            "privileged: the analytic law fed the true theta = g/f",
            privileged=True,
            family="oracle",
        ),
        ControllerSpec(
            "bias_oracle",
            "scftc_cli.versions.v1.controllers.analytic:BiasOracle",
            "privileged: the analytic law fed the true theta and beta = b/f",
            privileged=True,
            family="oracle",
        ),
    ),
    folder=Path(__file__).resolve().parent,
    study=StudyPlan(
        sensors_in_battery=False,
        regime_rule=REGIME_RULE,
        deployed_preference="rma_dob",
        crosscheck="scftc_cli.versions.v1.study:CROSSCHECK",
    ),
    trainers={
        **dict.fromkeys(TUNED, TUNER),
        "rma_student": "scftc_cli.versions.v1.training.rma:train_student",
        "rma_dob": "scftc_cli.versions.v1.training.rma:train_student",
        "e2e_ppo": "scftc_cli.versions.v1.training.ppo:train_e2e_ppo",
    },
    tuning="scftc_cli.versions.v1.training.tuning:TUNING",
    envs=(
        GymEnv(
            "scftc/AttitudeFTC-v1",
            "scftc_cli.versions.v1.envs:AttitudeFTCEnv",
            "scftc_cli.versions.v1.envs:AttitudeFTCVectorEnv",
        ),
    ),
    definition=("docs/benchmark.md", "## 12. The spec as data"),
    alias="V1",
)
