"""``scftc-v4`` as data: v3's agile mission recalibrated so that every ranked class tests fault
tolerance. The plant, environment, sensors, mission and observation are v3's (imported, not
copied); the fault classes that a fault-unaware integrator won on v3 are redrawn the way flight
makes them hard, a class ranks only if it passes the admission rule (``admission``), and the
diagnosis is ranked beside the settled ranking.

Every number of the version is here and nowhere else; its written definition is
``docs/benchmark-v4.md`` (a test checks that every value below appears in its table "The spec as
data"). The ranges were calibrated on the train split only; with the first board they are fixed.
"""

from __future__ import annotations

from scftc_cli.spec import (
    AdmissionRule,
    BenchmarkSpec,
    DiagnosisSpec,
    IntervalSet,
    closed,
    outside,
)
from scftc_cli.versions.v3.spec import (
    UNITS,
    V3,
    AgileFaultClass,
    AgilePlant,
    AgileSensors,
    AgileSplit,
    _above,
)


class V4Split(AgileSplit):
    """One split of ``scftc-v4``'s taxonomy: v3's ranges plus what the recalibrated classes draw.

    Attributes:
        flicker_gain: an ``intermittent`` wheel's gain factor during a burst (-1: it drives
            backwards, a failing commutation sensor), on top of its friction burst.
        creep_end_gain, creep_duration_s: an ``incipient`` fault is a spacecraft already flying
            on three wheels (one dead from the onset) whose second wheel degrades: its gain creeps
            linearly from 1 at the onset down to ``creep_end_gain`` over ``creep_duration_s``, then
            stays there, while its friction ramps as in v3.
        class_stored_momentum_nms: a class's own stored momentum, where it is not the split's
            ``stored_momentum_nms`` (the other classes keep that).
    """

    flicker_gain: float
    creep_end_gain: IntervalSet
    creep_duration_s: IntervalSet
    class_stored_momentum_nms: dict[str, IntervalSet]

    def for_class(self, name: str) -> AgileSplit:
        """The ranges class ``name`` draws from: these, with its own stored momentum if it has one."""
        if name in self.class_stored_momentum_nms:
            return self.model_copy(update={"stored_momentum_nms": self.class_stored_momentum_nms[name]})
        return self


class V4FaultClass(AgileFaultClass):
    """A ``scftc-v4`` actuator fault class: v3's flags plus the recalibrated kinds.

    Attributes:
        flicker: the ``intermittent`` wheel also misbehaves during its bursts (``flicker_gain``).
        creep: the ``incipient`` wheel's gain creeps down (``creep_end_gain``) and another wheel
            is dead.
    """

    flicker: bool = False
    creep: bool = False


RECALIBRATED = {
    "reversed_wheels",
    "double_gain_magnitude",
    "burst_multiplier",
    "burst_duration_s",
    "friction_ramp_end",
}
"""v3's split ranges that v4 sets anew (the others are v3's, copied from its spec at import)."""

V4 = BenchmarkSpec[AgilePlant, V4Split, AgileSensors](
    version="scftc-v4",
    title="the agile track recalibrated: every ranked class needs fault tolerance, diagnosis ranked",
    plant=V3.plant,
    sensors=V3.sensors,
    observation=V3.observation,
    action_dim=V3.action_dim,
    splits={
        "train": V4Split(
            **V3.splits["train"].model_dump(exclude=RECALIBRATED),
            reversed_wheels=(1,),
            double_gain_magnitude=outside(0.025, 0.04, 0.055, 0.07),
            burst_multiplier=closed(2.0, 10.0),
            burst_duration_s=closed(30.0, 120.0),
            flicker_gain=-1.0,
            creep_end_gain=outside(0.02, 0.035, 0.045, 0.06),
            creep_duration_s=closed(100.0, 300.0),
            friction_ramp_end=closed(1.5, 3.0),
            class_stored_momentum_nms={"double": closed(0.05, 0.2), "incipient": closed(0.05, 0.2)},
        ),
        "test": V4Split(
            **V3.splits["test"].model_dump(exclude=RECALIBRATED),
            reversed_wheels=(2, 3),
            double_gain_magnitude=closed(0.04, 0.055),
            burst_multiplier=_above(10.0, 20.0),
            burst_duration_s=_above(120.0, 240.0),
            flicker_gain=-1.0,
            creep_end_gain=closed(0.035, 0.045),
            creep_duration_s=_above(300.0, 400.0),
            friction_ramp_end=_above(3.0, 5.0),
            class_stored_momentum_nms={"double": _above(0.2, 0.25), "incipient": _above(0.2, 0.25)},
        ),
    },
    classes=(
        V4FaultClass(name="nominal", magnitude=False, reversals=False, healthy=True),
        V4FaultClass(name="sign", magnitude=False),
        V4FaultClass(name="gain"),
        V4FaultClass(name="gain_bias", bias=True),
        V4FaultClass(name="friction", friction=True),
        V4FaultClass(name="loss", dead=True),
        V4FaultClass(name="double", magnitude=False, reversals=False, double=True),
        V4FaultClass(name="intermittent", magnitude=False, reversals=False, intermittent=True, flicker=True),
        V4FaultClass(name="incipient", magnitude=False, reversals=False, incipient=True, creep=True),
        V4FaultClass(name="rod", magnitude=False, reversals=False, rod=True, dead=True),
        V4FaultClass(name="compound", bias=True, compound=True),
    ),
    sensor_classes=V3.sensor_classes,
    ranked_classes=(
        "sign",
        "gain",
        "gain_bias",
        "friction",
        "loss",
        "double",
        "intermittent",
        "incipient",
        "compound",
    ),
    diagnosis=DiagnosisSpec(units=UNITS, false_alarm_budget=0.01, detection="faulted_unit", ranked=True),
    admission=AdmissionRule(oracle="oracle", oracle_at_least=0.95, unaware="pid", unaware_at_most=0.50),
)
