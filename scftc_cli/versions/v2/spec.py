"""``scftc-v2`` as data: the flight-like track, four reaction wheels, noisy redundant sensors,
mid-flight faults.

Every number of the version is here and nowhere else; its written definition is
``docs/benchmark-v2.md`` (a test checks that every value below appears in its table "The spec as data").
"""

from __future__ import annotations

from typing import Literal

from scftc_cli.spec import (
    BenchmarkSpec,
    FaultClass,
    Interval,
    IntervalSet,
    ObservationField,
    PlantSpec,
    SensorFaultClass,
    SensorSpec,
    SplitSpec,
    closed,
    outside,
)

_R3 = 0.5773502691896258  # 1 / sqrt(3), the float64 nearest to it


class ReactionWheelPlant(PlantSpec):
    """``scftc-v2``'s testbed: a rigid hub with four balanced reaction wheels (docs/benchmark-v2.md).

    Attributes:
        spin_axes: one unit spin axis per wheel, body frame (tetrahedral: any three independent).
        h_max_nms, omega_max_rpm: wheel momentum at the speed limit; ``Js = h_max / Omega_max``,
            transverse ``Jt = Js / 2``.
        u_max_nm: motor torque cap per wheel.
        coulomb_nm, viscous_nms, omega_linear_rad_s: nominal bearing friction ``fC0``, ``cV`` and
            the half width ``wLC`` of the zone where friction is linear in speed.
        wheel_speed0_half_width_rpm: initial wheel speeds are uniform in +- this, per wheel.
    """

    kind: Literal["reaction-wheels"] = "reaction-wheels"
    inertia_nominal_kgm2: tuple[float, float, float] = (10.0, 8.0, 6.0)
    spin_axes: tuple[tuple[float, float, float], ...] = (
        (_R3, _R3, _R3),
        (_R3, -_R3, -_R3),
        (-_R3, _R3, -_R3),
        (-_R3, -_R3, _R3),
    )
    h_max_nms: float = 2.0
    omega_max_rpm: float = 6000.0
    u_max_nm: float = 0.1
    coulomb_nm: float = 5e-4
    viscous_nms: float = 0.0
    omega_linear_rad_s: float = 3.0
    dt_s: float = 0.5
    steps: int = 400
    sigma0_half_width: float = 0.5
    omega0_half_width_rad_s: float = 0.02
    wheel_speed0_half_width_rpm: float = 1000.0

    @property
    def n_wheels(self) -> int:
        return len(self.spin_axes)


class SensorSuite(SensorSpec):
    """``scftc-v2``'s sensors: noise figures a controller may know (never their draws).

    Attributes:
        star_tracker_heads: number of heads, each reporting the attitude with its own noise.
        star_tracker_noise_arcsec: white rotation noise per axis per sample, 1 sigma.
        gyro_arw_deg_sqrt_h: gyro angle random walk; per-sample sigma ``ARW / sqrt(dt)``.
        gyro_bias_deg_h: the constant gyro bias of an episode is uniform in +- this per axis.
        tachometer_noise_rad_s: white wheel-speed noise per sample, 1 sigma.
    """

    star_tracker_heads: int = 3
    star_tracker_noise_arcsec: float = 10.0
    gyro_arw_deg_sqrt_h: float = 0.15
    gyro_bias_deg_h: float = 0.5
    tachometer_noise_rad_s: float = 0.01


class WheelSplit(SplitSpec):
    """Parameter ranges of one split of ``scftc-v2``'s fault taxonomy (actuator faults per wheel).

    Attributes:
        onset_s: the fault (actuator or sensor) starts at the first step ``k`` with ``k dt >= t_f``.
        reversed_wheels: the number of reversed wheels is drawn uniformly from these.
        gain_magnitude, bias: per-wheel effectiveness magnitude and offset (a fraction of ``u_max``).
        friction_multiplier: one wheel's Coulomb friction becomes this times ``fC0`` (``friction``).
        head_bias_deg: rotation offset of one star-tracker head (``st_bias``).
        gyro_bias_step_deg_s: size per axis of the gyro-bias step (``gyro_bias``), random signs.
    """

    inertia_scale: IntervalSet
    onset_s: IntervalSet
    reversed_wheels: tuple[int, ...]
    gain_magnitude: IntervalSet
    bias: IntervalSet
    friction_multiplier: IntervalSet
    head_bias_deg: IntervalSet
    gyro_bias_step_deg_s: IntervalSet


V2 = BenchmarkSpec[ReactionWheelPlant, WheelSplit, SensorSuite](
    version="scftc-v2",
    title="the flight-like track: four reaction wheels, noisy redundant sensors, mid-flight faults",
    plant=ReactionWheelPlant(),
    sensors=SensorSuite(),
    observation=(
        ObservationField(name="star_tracker_heads", width=9, unit="MRP (three heads, zeros if invalid)"),
        ObservationField(name="star_tracker_valid", width=3, unit="1 valid, 0 invalid"),
        ObservationField(name="gyro", width=3, unit="rad/s"),
        ObservationField(name="tachometers", width=4, unit="rad/s"),
    ),
    action_dim=4,
    splits={
        "train": WheelSplit(
            inertia_scale=closed(0.8, 2.0),
            onset_s=closed(0.0, 30.0),
            reversed_wheels=(0, 1),
            gain_magnitude=closed(0.5, 1.5),
            bias=closed(-0.2, 0.2),
            friction_multiplier=closed(1.0, 20.0),
            head_bias_deg=closed(0.05, 0.3),
            gyro_bias_step_deg_s=closed(0.0, 0.015),
        ),
        "test": WheelSplit(
            inertia_scale=outside(0.7, 0.8, 2.0, 2.3),
            onset_s=IntervalSet(parts=(Interval(lo=30.0, hi=60.0, lo_closed=False),)),
            reversed_wheels=(2, 3),
            gain_magnitude=outside(0.3, 0.5, 1.5, 2.0),
            bias=outside(-0.3, -0.2, 0.2, 0.3),
            friction_multiplier=IntervalSet(parts=(Interval(lo=20.0, hi=60.0, lo_closed=False),)),
            head_bias_deg=IntervalSet(parts=(Interval(lo=0.3, hi=1.0, lo_closed=False),)),
            gyro_bias_step_deg_s=IntervalSet(parts=(Interval(lo=0.015, hi=0.03, lo_closed=False),)),
        ),
    },
    classes=(
        FaultClass(name="sign", magnitude=False),
        FaultClass(name="gain"),
        FaultClass(name="gain_bias", bias=True),
        FaultClass(name="friction", friction=True),
        FaultClass(name="loss", dead=True),
    ),
    sensor_classes=(
        SensorFaultClass(name="st_bias", kind="head_bias"),
        SensorFaultClass(name="st_stuck", kind="head_stuck"),
        SensorFaultClass(name="st_outage", kind="outage"),
        SensorFaultClass(name="gyro_bias", kind="gyro_step"),
    ),
    ranked_classes=("sign", "gain", "gain_bias", "friction", "loss"),
)
