"""What ``scftc-v2``'s classical ports are tuned over (``training/tuning.py`` searches it;
docs/controllers.md, "scftc-v2 ports").

The same search and objective as v1's, over the ports' boxes, on the pinned train cells of all
five actuator classes (and, for ``pid``, whose integrator is the one part of the battery that acts
on a gyro-bias step, the ``sign+gyro_bias`` sensor cell), 12 faults x 3 seeds per cell: 180
episodes, as v1's tuning set. The provenance score is the mean over the tuned cells on 50 x 10
episodes each, and every train cell (actuator and sensor) is scored for the record.
"""

from __future__ import annotations

from scftc_cli.training.tuning import Dim, TuneBudget, TuneSpec, Tuning
from scftc_cli.versions.v1.training import tuning as v1
from scftc_cli.versions.v2.controllers import adaptive, icl, nussbaum, pid, rls
from scftc_cli.versions.v2.spec import V2

BUDGETS: dict[str, TuneBudget] = {
    "quick": TuneBudget(n_faults=2, n_seeds=1, popsize=2, maxiter=2, final_faults=2, final_seeds=2),
    "full": TuneBudget(n_faults=12, n_seeds=3, popsize=10, maxiter=40, final_faults=50, final_seeds=10),
}
"""``scftc-v2``: 180 tuning episodes for the five actuator classes (v1 flies 180 over three), the
same differential-evolution effort as v1."""


CLASSES: tuple[str, ...] = tuple(V2.fault_classes)

_DITHER = (Dim("dither_amp", 0.0, 0.5), Dim("dither_steps", 0, 400, integer=True))  # 400: the whole episode

SPECS: dict[str, TuneSpec] = {
    pid.NAME: TuneSpec(
        pid.NAME,
        pid.PIDParams,
        pid.PID,
        v1.SPECS[pid.NAME].space,
        benchmark=V2.version,
        classes=(*CLASSES, "sign+gyro_bias"),  # the integrator removes a gyro-bias step's offset
    ),
    nussbaum.NAME: TuneSpec(
        nussbaum.NAME,
        nussbaum.NussbaumParams,
        nussbaum.Nussbaum,
        (*v1.SPECS[nussbaum.NAME].space, Dim("k_null", 0.0, 0.3)),
        benchmark=V2.version,
        classes=CLASSES,
    ),
    adaptive.NAME: TuneSpec(
        adaptive.NAME,
        adaptive.AdaptiveParams,
        adaptive.ClassicalAdaptive,
        (
            Dim("vote_min_da", 0.01, 0.3, log=True),
            Dim("vote_threshold", 1.0, 8.0),
            Dim("gamma_m", 0.05, 1.9, log=True),
            Dim("gamma_b", 0.0, 1.5),
            Dim("gamma_kappa", 0.0, 1.5),
            Dim("sigma_mod", 0.0, 0.1),
            Dim("dead_zone", 0.0, 0.02),
            *_DITHER,
            Dim("detect_threshold", 0.005, 0.2, log=True),
            Dim("detect_steps", 1, 6, integer=True),
        ),
        benchmark=V2.version,
        classes=CLASSES,
    ),
    icl.NAME: TuneSpec(
        icl.NAME,
        icl.ICLParams,
        icl.ICLAdaptive,
        (
            Dim("window", 1, 8, integer=True),
            Dim("stack_size", 3, 20, integer=True),
            Dim("gamma_cl", 0.1, 1.9, log=True),  # >= 0.1: the concurrent-learning term stays in the law
            Dim("gamma_inst", 0.0, 1.9),
            Dim("offset_ratio", 0.01, 1.0, log=True),
            Dim("friction_ratio", 0.01, 1.0, log=True),
            *_DITHER,
            Dim("detect_threshold", 0.005, 0.2, log=True),
            Dim("detect_steps", 1, 6, integer=True),
        ),
        benchmark=V2.version,
        classes=CLASSES,
    ),
    rls.NAME: TuneSpec(
        rls.NAME,
        rls.RLSParams,
        rls.RLSDob,
        (
            Dim("forgetting", 0.9, 1.0),
            Dim("p0_g", 1.0, 1e4, log=True),
            Dim("p0_b", 0.1, 1e3, log=True),
            Dim("p0_kappa", 1e-4, 10.0, log=True),
            Dim("p_max", 10.0, 1e5, log=True),
            *_DITHER,
            Dim("latch_min_steps", 2, 30, integer=True),
            Dim("latch_tol", 1e-4, 0.1, log=True),
            Dim("latch_prior_ratio", 1e-4, 0.1, log=True),
            Dim("observer_gain", 0.01, 0.5, log=True),
            Dim("detect_threshold", 0.005, 0.2, log=True),
            Dim("detect_steps", 1, 6, integer=True),
        ),
        benchmark=V2.version,
        classes=CLASSES,
    ),
}
"""The ``scftc-v2`` ports tuned here (``controllers/``): v1's boxes where a parameter carries over,
for ``nussbaum`` the gain of its null-space term (the fourth wheel's freedom, which v1 does not
have), for ``rls_dob`` a dither allowed to last the whole episode (in the null space of the wheel
array it costs the hub nothing once the estimates are right) and the change test's parameters."""


TUNING = Tuning(specs=SPECS, budgets=BUDGETS, score_sensor_cells=True)
