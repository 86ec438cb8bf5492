"""What ``scftc-v4``'s tunable ports are tuned over (``scftc_cli/training/tuning.py`` searches it).

v3's boxes (``versions/v3/training/tuning.py``), on v4's pinned train cells of every actuator
class, ``nominal`` included, and ``sign+gyro_bias`` for ``pid`` as on v2 and v3. The ``full``
budget is smaller than v3's (6 faults x 2 seeds per cell, 6 x 5 candidates, 15 generations against
v3's 12 x 3, 10 x 5, 40): v3's run took hours in resumed legs, and the admission rule asks of
``pid`` only that it be a fair, train-tuned fault-unaware integrator. The committed file says the
budget it was tuned with.
"""

from __future__ import annotations

from scftc_cli.training.tuning import Dim, TuneBudget, TuneSpec, Tuning
from scftc_cli.versions.v2.controllers.pid import PIDParams
from scftc_cli.versions.v3.training import tuning as v3
from scftc_cli.versions.v3.training.tuning import PID_SPACE
from scftc_cli.versions.v4.controllers import analytic, pid, rls
from scftc_cli.versions.v4.spec import V4

BUDGETS: dict[str, TuneBudget] = {
    "quick": TuneBudget(n_faults=1, n_seeds=1, popsize=1, maxiter=1, final_faults=1, final_seeds=1),
    "full": TuneBudget(n_faults=6, n_seeds=2, popsize=6, maxiter=15, final_faults=50, final_seeds=10),
}

CLASSES: tuple[str, ...] = tuple(V4.fault_classes)

SPECS: dict[str, TuneSpec] = {
    pid.NAME: TuneSpec(
        pid.NAME,
        PIDParams,
        pid.PID,
        PID_SPACE,
        benchmark=V4.version,
        classes=(*CLASSES, "sign+gyro_bias"),
        per_episode_params=True,
    ),
    rls.NAME: TuneSpec(
        rls.NAME,
        rls.V4RLSParams,
        rls.RLSDob,
        (
            *v3.SPECS[rls.NAME].space,
            Dim("kp_s2", 0.005, 5.0, log=True),
            Dim("kd_s", 0.03, 3.0, log=True),
            Dim("dead_below", 0.005, 0.2, log=True),
        ),
        benchmark=V4.version,
        classes=CLASSES,
        per_episode_params=True,
        start_from=(rls.NAME, v3.V3.version),
        budgets={
            "quick": BUDGETS["quick"],
            "full": TuneBudget(n_faults=4, n_seeds=2, popsize=2, maxiter=8, final_faults=50, final_seeds=10),
        },
    ),
    analytic.NAME: TuneSpec(
        analytic.NAME,
        analytic.LawGains,
        analytic.Oracle,
        (Dim("kp_s2", 0.005, 5.0, log=True), Dim("kd_s", 0.03, 3.0, log=True)),
        benchmark=V4.version,
        classes=CLASSES,
        per_episode_params=True,
        budgets={
            "quick": BUDGETS["quick"],
            "full": TuneBudget(
                n_faults=25, n_seeds=2, popsize=4, maxiter=10, final_faults=50, final_seeds=10
            ),
        },
    ),
}
"""The ``scftc-v4`` ports tuned here: ``pid`` over v3's ``PID_SPACE``; ``rls_dob`` over v3's box plus
its law's PD gains (``pid``'s ranges) and its dead-wheel threshold, started from v3's tuned
settings, with a smaller effort (2 x 14 candidates, 8 generations, 4 faults x
2 seeds per cell): its estimator costs several times ``pid``'s per step; and the privileged
``oracle``'s two law gains (``pid``'s ranges, from v2's 0.04 and 0.14), which the teacher flies
too, on 25 faults x 2 seeds per cell: the oracle settles nearly every train episode, and on 6 x 2
the search could not tell gains that settle 97 % of ``double`` from gains that settle 99.8 %
(every candidate settled 0.999 of its set and the tie-break chose the lower gains)."""

TUNING = Tuning(specs=SPECS, budgets=BUDGETS, score_sensor_cells=True)
