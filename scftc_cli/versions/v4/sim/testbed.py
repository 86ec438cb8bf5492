"""``scftc-v4``'s simulator: v3's (plant on three backends, sensors, mission windows, context,
diagnosis truth), flying v4's draws (``sim/faults.py``)."""

from __future__ import annotations

from scftc_cli.versions.v3.sim.testbed import AgileTestbed
from scftc_cli.versions.v4.sim.faults import pinned_episodes
from scftc_cli.versions.v4.spec import V4


class V4Testbed(AgileTestbed):
    """``scftc-v4`` (docs/benchmark-v4.md): v3's testbed on v4's spec and draws."""

    spec = V4  # type: ignore[assignment]  # v4's splits are v3's plus its own ranges
    pinned = staticmethod(pinned_episodes)


TESTBED = V4Testbed()
