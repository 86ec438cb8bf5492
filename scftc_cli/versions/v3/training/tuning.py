"""What ``scftc-v3``'s tunable ports are tuned over (``scftc_cli/training/tuning.py`` searches it).

The same search, objective and effort as v1's and v2's (differential evolution over their boxes,
``pid``'s gains allowed higher (``PID_SPACE``), 12 faults x 3 seeds per cell), on the pinned train
cells of all eleven actuator classes, ``nominal`` included (a port that hurts a healthy spacecraft
pays for it), and, for ``pid``, whose integrator is what acts on a gyro-bias step, the
``sign+gyro_bias`` sensor cell, as on v2. A v3 episode is six times a v2 one (2400 steps), so a
full tuning run costs about six times v2's; ``pid`` reads its parameters per episode, so each DE
generation (50 candidates x 432 episodes) flies as one batch on the parallel kernels, with scipy's
deferred update (``training/tuning.py``).
"""

from __future__ import annotations

from scftc_cli.training.tuning import Dim, TuneBudget, TuneSpec, Tuning
from scftc_cli.versions.v2.controllers.pid import PIDParams
from scftc_cli.versions.v2.controllers.rls import RLSParams
from scftc_cli.versions.v2.training import tuning as v2
from scftc_cli.versions.v3.controllers import pid, rls
from scftc_cli.versions.v3.spec import V3

BUDGETS: dict[str, TuneBudget] = {
    "quick": TuneBudget(n_faults=1, n_seeds=1, popsize=1, maxiter=1, final_faults=1, final_seeds=1),
    "full": TuneBudget(n_faults=12, n_seeds=3, popsize=10, maxiter=40, final_faults=50, final_seeds=10),
}

CLASSES: tuple[str, ...] = tuple(V3.fault_classes)

PID_SPACE: tuple[Dim, ...] = (
    Dim("kp_s2", 0.005, 5.0, log=True),
    Dim("kd_s", 0.03, 3.0, log=True),
    Dim("ki_s3", 1e-5, 1.0, log=True),
    Dim("integral_cap", 0.05, 1.0),
    Dim("integrate_below", 0.01, 1.0, log=True),
)
"""v1's ``pid`` box with the gains' upper edges raised (``kp_s2`` 0.5 to 5, ``kd_s`` 1.5 to 3, ``ki_s3``
0.01 to 1): a full tuning over v1's box ended at its edge (``kp_s2`` 0.4997, ``ki_s3`` 0.00999),
so that box, not the controller, set the result. ``kd_s`` stops at 3 /s: with 0.5 s steps the rate
loop's discrete pole ``1 - kd dt`` leaves the unit circle at ``kd = 4``."""

SPECS: dict[str, TuneSpec] = {
    pid.NAME: TuneSpec(
        pid.NAME,
        PIDParams,
        pid.PID,
        PID_SPACE,
        benchmark=V3.version,
        classes=(*CLASSES, "sign+gyro_bias"),
        per_episode_params=True,
    ),
    rls.NAME: TuneSpec(
        rls.NAME,
        RLSParams,
        rls.RLSDob,
        tuple(
            Dim("dither_steps", 0, V3.steps, integer=True) if d.name == "dither_steps" else d
            for d in v2.SPECS[rls.NAME].space
        ),
        benchmark=V3.version,
        classes=CLASSES,
        per_episode_params=True,
    ),
}
"""The ``scftc-v3`` ports tuned here: ``pid`` over ``PID_SPACE``, ``rls_dob`` over v2's, its dither
allowed to last the whole episode as on v2 (2400 steps here)."""

TUNING = Tuning(specs=SPECS, budgets=BUDGETS, score_sensor_cells=True)
