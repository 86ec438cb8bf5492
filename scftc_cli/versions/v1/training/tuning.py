"""What ``scftc-v1``'s classical controllers are tuned over (``training/tuning.py`` searches it).

The tuning episodes are the pinned train cells of ``sign``, ``gain`` and ``gain_bias``; ``loss`` is
left out because no smooth law of the battery settles a dead axis and it carries no signal, except
for ``rls_plan``, whose dead-axis plan is tuned on it. ``full``: 20 faults x 3 seeds per class
(180 episodes), minutes per controller; the provenance score is the mean over the tuned classes
on 50 x 10 episodes each.
"""

from __future__ import annotations

from scftc_cli.training.tuning import Dim, TuneBudget, TuneSpec, Tuning
from scftc_cli.versions.v1.controllers.adaptive import NAME as ADAPTIVE
from scftc_cli.versions.v1.controllers.adaptive import AdaptiveParams, ClassicalAdaptive
from scftc_cli.versions.v1.controllers.icl import NAME as ICL
from scftc_cli.versions.v1.controllers.icl import ICLAdaptive, ICLParams
from scftc_cli.versions.v1.controllers.nussbaum import NAME as NUSSBAUM
from scftc_cli.versions.v1.controllers.nussbaum import Nussbaum, NussbaumParams
from scftc_cli.versions.v1.controllers.pid import NAME as PID_NAME
from scftc_cli.versions.v1.controllers.pid import PID, PIDParams
from scftc_cli.versions.v1.controllers.plan import NAME as PLAN
from scftc_cli.versions.v1.controllers.plan import PlanParams, RLSPlan
from scftc_cli.versions.v1.controllers.rls import NAME as RLS
from scftc_cli.versions.v1.controllers.rls import RLSDob, RLSParams
from scftc_cli.versions.v1.spec import V1

TUNE_CLASSES: tuple[str, ...] = ("sign", "gain", "gain_bias")

BUDGETS: dict[str, TuneBudget] = {
    "quick": TuneBudget(n_faults=3, n_seeds=2, popsize=2, maxiter=2, final_faults=5, final_seeds=2),
    "full": TuneBudget(n_faults=20, n_seeds=3, popsize=10, maxiter=40, final_faults=50, final_seeds=10),
}


SPECS: dict[str, TuneSpec] = {
    PID_NAME: TuneSpec(
        PID_NAME,
        PIDParams,
        PID,
        (
            Dim("kp_s2", 0.005, 0.5, log=True),
            Dim("kd_s", 0.03, 1.5, log=True),
            Dim("ki_s3", 1e-5, 1e-2, log=True),
            Dim("integral_cap", 0.05, 1.0),
            Dim("integrate_below", 0.01, 1.0, log=True),
        ),
        classes=TUNE_CLASSES,
        benchmark=V1.version,
    ),
    ADAPTIVE: TuneSpec(
        ADAPTIVE,
        AdaptiveParams,
        ClassicalAdaptive,
        (
            Dim("vote_min_da", 0.01, 0.3, log=True),
            Dim("vote_threshold", 1.0, 8.0),
            Dim("gamma_m", 0.05, 1.9, log=True),
            Dim("gamma_beta", 0.0, 1.5),
            Dim("sigma_mod", 0.0, 0.1),
            Dim("dead_zone", 0.0, 0.02),
            Dim("dither_amp", 0.0, 0.5),
            Dim("dither_steps", 0, 30, integer=True),
        ),
        classes=TUNE_CLASSES,
        benchmark=V1.version,
    ),
    ICL: TuneSpec(
        ICL,
        ICLParams,
        ICLAdaptive,
        (
            Dim("window", 1, 8, integer=True),
            Dim("stack_size", 3, 20, integer=True),
            Dim("gamma_cl", 0.1, 1.9, log=True),  # >= 0.1: the concurrent-learning term stays in the law
            Dim("gamma_inst", 0.0, 1.9),
            Dim("dither_amp", 0.0, 0.6),
            Dim("dither_steps", 0, 80, integer=True),
        ),
        classes=TUNE_CLASSES,
        benchmark=V1.version,
    ),
    NUSSBAUM: TuneSpec(
        NUSSBAUM,
        NussbaumParams,
        Nussbaum,
        (
            Dim("gamma", 0.005, 2.0, log=True),
            Dim("zeta0", 0.2, 1.5),
            Dim("dead_zone", 0.001, 0.2, log=True),
            Dim("gamma_d", 0.0, 2.0),
            Dim("kp_s2", 0.01, 0.1, log=True),
            Dim("kd_s", 0.05, 0.5, log=True),
        ),
        classes=TUNE_CLASSES,
        benchmark=V1.version,
    ),
    RLS: TuneSpec(
        RLS,
        RLSParams,
        RLSDob,
        (
            Dim("forgetting", 0.9, 1.0),
            Dim("p0_theta", 1.0, 1e4, log=True),
            Dim("p0_beta", 0.1, 1e3, log=True),
            Dim("p_max", 10.0, 1e5, log=True),
            Dim("dither_amp", 0.0, 0.5),
            Dim("dither_steps", 0, 20, integer=True),
            Dim("latch_min_steps", 2, 30, integer=True),
            Dim("latch_tol", 1e-4, 0.1, log=True),
            Dim("latch_prior_ratio", 1e-4, 0.1, log=True),
            Dim("observer_gain", 0.01, 0.5, log=True),
        ),
        classes=TUNE_CLASSES,
        benchmark=V1.version,
    ),
    # identification keeps rls_dob's tuned values; the plan's physics (authorities, slew times,
    # the Euler sequence) comes from the identified theta, never from tuned durations
    PLAN: TuneSpec(
        PLAN,
        PlanParams,
        RLSPlan,
        (
            Dim("eta", 0.6, 0.97),
            Dim("rho", 0.0, 0.6),
            Dim("tol_angle", 2e-5, 5e-4, log=True),
            Dim("tol_rate", 5e-6, 1e-4, log=True),
            Dim("tol_dead_rate", 5e-7, 1e-5, log=True),
            Dim("replan_deg", 0.03, 0.15),
        ),
        classes=("sign", "gain", "gain_bias", "loss"),
        benchmark=V1.version,
    ),
}


TUNING = Tuning(specs=SPECS, budgets=BUDGETS)
