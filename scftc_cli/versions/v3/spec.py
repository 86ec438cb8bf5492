"""``scftc-v3`` as data: the agile track. v2's hub and four wheels in a low Earth orbit, with
environment torques, three magnetorquer rods, a magnetometer, a mission of three pointing windows
joined by slews, faults that come two at a time, come and go, or creep in, healthy episodes, and a
scored diagnosis.

Every number of the version is here and nowhere else; its written definition is
``docs/benchmark-v3.md`` (a test checks that every value below appears in its table "The spec as
data"). The ranges were calibrated on the train split; with the first board they are fixed:
changing any of them makes a new version.
"""

from __future__ import annotations

from typing import Literal

from scftc_cli.spec import (
    BenchmarkSpec,
    DiagnosisSpec,
    FaultClass,
    Interval,
    IntervalSet,
    ObservationField,
    SensorFaultClass,
    closed,
    outside,
)
from scftc_cli.versions.v2.spec import ReactionWheelPlant, SensorSuite, WheelSplit


def _above(lo: float, hi: float) -> IntervalSet:
    """``(lo, hi]``: a held-out band above a train range."""
    return IntervalSet(parts=(Interval(lo=lo, hi=hi, lo_closed=False),))


class AgilePlant(ReactionWheelPlant):
    """``scftc-v3``'s testbed: v2's hub and wheels (unchanged) in orbit, plus rods and a mission.

    Attributes:
        kind: what the actuators are.
        steps: 2400 steps of 0.5 s: 1200 s, three windows.
        window_steps: steps per pointing window; the target changes at each window's start.
        slew_deg: each later target is the previous one turned by this angle about a random axis.
        altitude_km, inclination_deg: the circular orbit's altitude and inclination; the node, the
            argument of latitude and the Earth's rotation angle (where the dipole points) are
            uniform in [0, 360) deg.
        mu_m3_s2: Earth's gravitational parameter (point mass).
        igrf_g10_t, igrf_g11_t, igrf_h11_t: IGRF-2020 first-degree Gauss coefficients (tesla).
        rod_dipole_max_am2: dipole of each of the three rods (body axes) at command 1.
        facet_area_m2, facet_specular, facet_diffuse: the one sunlit facet (a solar array).
        facet_cop_m: the facet's centre of pressure is this far from the centre of mass, in a
            random direction; its normal and the Sun's direction are random unit vectors.
        max_bursts: an intermittent fault's bursts after the first this many are dropped.
        feasibility_margin: a dead-wheel episode is redrawn unless the three working wheels can
            store the system momentum, less ``unload_allowance_nms``, at every target from the
            onset's window on, with this fraction of their envelope.
        unload_allowance_nms: momentum the rods can be counted on to remove over an episode.
        health_gain_tolerance, health_offset_tolerance, health_friction_tolerance: the diagnosis
            truth counts a wheel healthy while its gain magnitude is within this of 1, its offset
            within this fraction of ``u_max`` and its friction multipliers (constant, ramp end,
            burst) at most this; beyond, degraded.
    """

    kind: Literal["reaction-wheels-rods"] = "reaction-wheels-rods"  # type: ignore[assignment]
    steps: int = 2400
    window_steps: int = 800
    slew_deg: IntervalSet = closed(20.0, 120.0)
    altitude_km: IntervalSet = closed(500.0, 700.0)
    inclination_deg: IntervalSet = closed(40.0, 98.0)
    mu_m3_s2: float = 398600.4418e9
    igrf_g10_t: float = -29404.8e-9
    igrf_g11_t: float = -1450.9e-9
    igrf_h11_t: float = 4652.5e-9
    rod_dipole_max_am2: float = 10.0
    facet_area_m2: float = 2.0
    facet_specular: float = 0.1
    facet_diffuse: float = 0.1
    facet_cop_m: IntervalSet = closed(0.05, 0.3)
    max_bursts: int = 32
    feasibility_margin: float = 0.95
    unload_allowance_nms: float = 0.2
    health_gain_tolerance: float = 0.1
    health_offset_tolerance: float = 0.02
    health_friction_tolerance: float = 1.5

    @property
    def windows(self) -> int:
        return self.steps // self.window_steps


class AgileSensors(SensorSuite):
    """v2's sensors plus a three-axis magnetometer (body frame, tesla).

    Attributes:
        magnetometer_noise_t: white noise per axis per sample, 1 sigma.
        mag_spike_probability, mag_spike_amount: a spiking magnetometer multiplies each axis's
            reading by ``amount`` with this probability each step.
    """

    magnetometer_noise_t: float = 50e-9
    mag_spike_probability: float = 0.1
    mag_spike_amount: float = 2.0


class AgileSplit(WheelSplit):
    """One split of ``scftc-v3``'s taxonomy: v2's ranges (onsets moved into windows 2 and 3) plus
    the mission's stored momentum, the residual dipole and the new fault classes' ranges.

    Attributes:
        stored_momentum_nms: ``|h|`` of the system momentum the wheels hold at the start, random
            direction.
        residual_dipole_am2: size of the constant body dipole, random direction.
        double_gain_magnitude: the degraded wheel's magnitude in a ``double`` fault.
        burst_multiplier, burst_duration_s, burst_interval_s: an ``intermittent`` wheel's nominal
            Coulomb friction is multiplied by the factor during bursts; the first burst starts at
            the onset, the next ones after exponential gaps of this mean (a Poisson process).
        friction_ramp_end: an ``incipient`` wheel's friction multiplier, 1 at the onset, reaches
            this at the episode's end.
        rod_fault: ``reversed`` (one rod's dipole reversed) or ``dead_and_half`` (one rod dead,
            another at half dipole).
        compound_sensor: the sensor fault a ``compound`` episode adds to its ``gain_bias`` fault.
        mag_bias_t: size of a ``mag_bias`` fault's constant vector, random direction (tesla).
        outage_duration_s: how long an ``st_outage`` keeps every head out before they come back (a
            Sun, Earth or Moon blinding of the whole star tracker).
    """

    stored_momentum_nms: IntervalSet
    residual_dipole_am2: IntervalSet
    double_gain_magnitude: IntervalSet
    burst_multiplier: IntervalSet
    burst_duration_s: IntervalSet
    burst_interval_s: float
    friction_ramp_end: IntervalSet
    rod_fault: Literal["reversed", "dead_and_half"]
    compound_sensor: str
    mag_bias_t: IntervalSet
    outage_duration_s: IntervalSet

    def for_class(self, name: str) -> AgileSplit:
        """The ranges fault class ``name`` draws from: these (a later version's split may give a
        class its own, e.g. ``scftc-v4``'s ``double`` its stored momentum)."""
        return self


class AgileFaultClass(FaultClass):
    """A ``scftc-v3`` actuator fault class: v2's flags plus the new kinds.

    Attributes:
        reversals: the class draws the split's reversed wheels (v2's five classes do).
        double: one wheel dead and another degraded (``double_gain_magnitude``).
        intermittent: one wheel's friction bursts.
        incipient: one wheel's friction ramps up.
        rod: one or two rods faulted (``rod_fault``); the ``rod`` class pairs them with a dead
            wheel (``dead``), so that the three wheels left need the rods' unloading.
        compound: a sensor fault (``compound_sensor``) at the same onset.
        healthy: no fault at all (``nominal``).
    """

    reversals: bool = True
    double: bool = False
    intermittent: bool = False
    incipient: bool = False
    rod: bool = False
    compound: bool = False
    healthy: bool = False


WHEEL_UNITS = ("wheel_1", "wheel_2", "wheel_3", "wheel_4")
ROD_UNITS = ("rod_x", "rod_y", "rod_z")
HEAD_UNITS = ("head_1", "head_2", "head_3")
UNITS = (*WHEEL_UNITS, *ROD_UNITS, *HEAD_UNITS, "gyro", "magnetometer")

V3 = BenchmarkSpec[AgilePlant, AgileSplit, AgileSensors](
    version="scftc-v3",
    title="the agile track: slews in orbit, magnetorquers, compound and creeping faults, scored diagnosis",
    plant=AgilePlant(),
    sensors=AgileSensors(),
    observation=(
        ObservationField(name="star_tracker_heads", width=9, unit="MRP (three heads, zeros if invalid)"),
        ObservationField(name="star_tracker_valid", width=3, unit="1 valid, 0 invalid"),
        ObservationField(name="gyro", width=3, unit="rad/s"),
        ObservationField(name="tachometers", width=4, unit="rad/s"),
        ObservationField(name="magnetometer", width=3, unit="T (body frame)"),
        ObservationField(name="target", width=3, unit="MRP (inertial, the current window's)"),
        ObservationField(name="time_left", width=1, unit="s (in the current window)"),
    ),
    action_dim=7,
    splits={
        "train": AgileSplit(
            inertia_scale=closed(0.8, 2.0),
            onset_s=closed(0.0, 500.0),
            reversed_wheels=(0, 1),
            gain_magnitude=closed(0.5, 1.5),
            bias=closed(-0.2, 0.2),
            friction_multiplier=closed(1.0, 20.0),
            head_bias_deg=closed(0.05, 0.3),
            gyro_bias_step_deg_s=closed(0.0, 0.015),
            stored_momentum_nms=closed(0.5, 1.5),
            residual_dipole_am2=closed(0.0, 0.5),
            double_gain_magnitude=closed(0.4, 0.7),
            burst_multiplier=closed(10.0, 30.0),
            burst_duration_s=closed(5.0, 60.0),
            burst_interval_s=200.0,
            friction_ramp_end=closed(5.0, 30.0),
            rod_fault="reversed",
            compound_sensor="st_bias",
            mag_bias_t=closed(1e-6, 5e-6),
            outage_duration_s=closed(60.0, 300.0),
        ),
        "test": AgileSplit(
            inertia_scale=outside(0.7, 0.8, 2.0, 2.3),
            onset_s=_above(500.0, 1000.0),
            reversed_wheels=(2, 3),
            gain_magnitude=outside(0.3, 0.5, 1.5, 2.0),
            bias=outside(-0.3, -0.2, 0.2, 0.3),
            friction_multiplier=_above(20.0, 60.0),
            head_bias_deg=_above(0.3, 1.0),
            gyro_bias_step_deg_s=_above(0.015, 0.03),
            stored_momentum_nms=_above(1.5, 1.9),
            residual_dipole_am2=_above(0.5, 1.0),
            double_gain_magnitude=IntervalSet(parts=(Interval(lo=0.2, hi=0.4, hi_closed=False),)),
            burst_multiplier=_above(30.0, 60.0),
            burst_duration_s=_above(60.0, 200.0),
            burst_interval_s=200.0,
            friction_ramp_end=_above(30.0, 60.0),
            rod_fault="dead_and_half",
            compound_sensor="gyro_bias",
            mag_bias_t=_above(5e-6, 15e-6),
            outage_duration_s=_above(300.0, 600.0),
        ),
    },
    classes=(
        AgileFaultClass(name="nominal", magnitude=False, reversals=False, healthy=True),
        AgileFaultClass(name="sign", magnitude=False),
        AgileFaultClass(name="gain"),
        AgileFaultClass(name="gain_bias", bias=True),
        AgileFaultClass(name="friction", friction=True),
        AgileFaultClass(name="loss", dead=True),
        AgileFaultClass(name="double", magnitude=False, reversals=False, double=True),
        AgileFaultClass(name="intermittent", magnitude=False, reversals=False, intermittent=True),
        AgileFaultClass(name="incipient", magnitude=False, reversals=False, incipient=True),
        AgileFaultClass(name="rod", magnitude=False, reversals=False, rod=True, dead=True),
        AgileFaultClass(name="compound", bias=True, compound=True),
    ),
    sensor_classes=(
        SensorFaultClass(name="st_bias", kind="head_bias"),
        SensorFaultClass(name="st_stuck", kind="head_stuck"),
        SensorFaultClass(name="st_outage", kind="outage"),
        SensorFaultClass(name="gyro_bias", kind="gyro_step"),
        SensorFaultClass(name="mag_bias", kind="magnetometer_bias"),
        SensorFaultClass(name="mag_spike", kind="magnetometer_spike"),
    ),
    ranked_classes=(
        "nominal",
        "sign",
        "gain",
        "gain_bias",
        "friction",
        "loss",
        "double",
        "intermittent",
        "incipient",
        "rod",
        "compound",
    ),
    diagnosis=DiagnosisSpec(units=UNITS, false_alarm_budget=0.01),
)
