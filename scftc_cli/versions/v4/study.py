"""``scftc-v4``'s Basilisk cross-check plan: v3's (``versions/v3/study.py``: the whole plant in
orbit on both backends, the one-step replay from every recorded Basilisk state, each flight held to
the tolerance or to its rounding twin's departure) on v4's held-out cells. v4's own faults are
time-varying wheel gains (a creeping gain, a wheel driving backwards inside its bursts): the
Basilisk backend reads them per step through the same ``faults_at`` the reference plant steps
with, so they are compared like every other fault.

The default run flies ``pd`` and the privileged ``teacher`` (``scftc crosscheck --benchmark
scftc-v4``), as on v3.
"""

from __future__ import annotations

from typing import ClassVar

from scftc_cli.evaluate import Cell
from scftc_cli.versions.v3.study import MissionCrosscheckResult, mission_plan
from scftc_cli.versions.v4.spec import V4

# v3's order (a short check flies a reversed wheel, friction, a dead wheel, a rod fault first),
# with v4's recalibrated classes, the new kinds early: a weak second wheel, one creeping down,
# one driving backwards in bursts; then every sensor fault on top of sign faults.
GROUPS = (
    Cell("test", "sign"),
    Cell("test", "double"),
    Cell("test", "incipient"),
    Cell("test", "intermittent"),
    Cell("test", "friction"),
    Cell("test", "loss"),
    Cell("test", "rod"),
    Cell("test", "compound"),
    Cell("test", "gain_bias"),
    Cell("test", "gain"),
    Cell("test", "nominal"),
    Cell("test", "sign", "st_bias"),
    Cell("test", "sign", "st_outage"),
    Cell("test", "sign", "st_stuck"),
    Cell("test", "sign", "gyro_bias"),
    Cell("test", "sign", "mag_bias"),
    Cell("test", "sign", "mag_spike"),
)


class V4CrosscheckResult(MissionCrosscheckResult):
    """v3's result and checks, reported as ``scftc-v4``'s."""

    benchmark_version: ClassVar[str] = V4.version


CROSSCHECK = mission_plan(V4, GROUPS, V4CrosscheckResult)
