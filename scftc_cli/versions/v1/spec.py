"""``scftc-v1`` as data: the source study's testbed, torques on the body, perfect sensors.

Every number of the version is here and nowhere else; its written definition is
``docs/benchmark.md`` (a test checks that every value below appears in its table "The spec as data").
"""

from __future__ import annotations

from typing import Literal

from scftc_cli.spec import (
    BenchmarkSpec,
    FaultClass,
    IntervalSet,
    ObservationField,
    PlantSpec,
    SensorFaultClass,
    SensorSpec,
    SplitSpec,
    closed,
    outside,
)


class RigidBodyPlant(PlantSpec):
    """``scftc-v1``'s testbed: a rigid body with three body-axis torques (docs/benchmark.md)."""

    kind: Literal["rigid-body-torques"] = "rigid-body-torques"
    inertia_nominal_kgm2: tuple[float, float, float] = (10.0, 8.0, 6.0)
    dt_s: float = 0.5
    steps: int = 400
    tau_max_nm: float = 0.2
    sigma0_half_width: float = 0.5
    omega0_half_width_rad_s: float = 0.02


class RigidBodySplit(SplitSpec):
    """Parameter ranges of one split of ``scftc-v1``'s actuator-fault taxonomy."""

    inertia_scale: IntervalSet
    gain_magnitude: IntervalSet
    reversed_axes: tuple[int, ...]
    bias: IntervalSet


V1 = BenchmarkSpec[RigidBodyPlant, RigidBodySplit, SensorSpec](
    version="scftc-v1",
    title="the source study's testbed: torques on the body, perfect sensors",
    plant=RigidBodyPlant(),
    observation=(
        ObservationField(name="sigma_meas", width=3, unit="MRP"),
        ObservationField(name="omega_meas", width=3, unit="rad/s"),
    ),
    action_dim=3,
    splits={
        "train": RigidBodySplit(
            inertia_scale=closed(0.8, 2.0),
            gain_magnitude=closed(0.5, 1.5),
            reversed_axes=(0, 1),
            bias=closed(-0.2, 0.2),
        ),
        "test": RigidBodySplit(
            inertia_scale=outside(0.7, 0.8, 2.0, 2.3),
            gain_magnitude=outside(0.3, 0.5, 1.5, 2.0),
            reversed_axes=(2, 3),
            bias=outside(-0.3, -0.2, 0.2, 0.3),
        ),
    },
    classes=(
        FaultClass(name="sign", magnitude=False),
        FaultClass(name="gain"),
        FaultClass(name="gain_bias", bias=True),
        FaultClass(name="loss", dead=True),
    ),
    sensor_classes=(
        SensorFaultClass(name="bias_0.1", kind="bias", angle_deg=0.1),
        SensorFaultClass(name="bias_0.2", kind="bias", angle_deg=0.2),
        SensorFaultClass(name="bias_0.3", kind="bias", angle_deg=0.3),
        SensorFaultClass(name="bias_0.5", kind="bias", angle_deg=0.5),
        SensorFaultClass(name="dropout", kind="dropout"),
        SensorFaultClass(name="stuck", kind="stuck"),
    ),
    ranked_classes=("sign", "gain", "gain_bias"),
)
