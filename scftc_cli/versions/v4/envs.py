"""``scftc/AttitudeFTC-v4``: ``scftc-v4``'s episodes in v3's gymnasium environment
(``versions/v3/envs.py``: the same observation, action, reward and vector stepping), drawn from
v4's sampler over its eleven actuator classes.

Training flies the train split; the held-out split is there for evaluation (every learned row was
trained while v4 was a draft, when the environment refused its held-out split).
"""

from __future__ import annotations

from scftc_cli.envs.batch import BatchEnv, BatchVectorEnv
from scftc_cli.versions.v3.envs import MissionBatch
from scftc_cli.versions.v4.sim.faults import pinned_episodes
from scftc_cli.versions.v4.sim.testbed import TESTBED
from scftc_cli.versions.v4.spec import V4

ENV_ID = "scftc/AttitudeFTC-v4"


class V4MissionBatch(MissionBatch):
    """``n`` ``scftc-v4`` episodes flown together (v3's ``MissionBatch`` on v4's draws)."""

    spec = V4  # type: ignore[assignment]  # v4's splits are v3's plus its own ranges
    testbed = TESTBED
    default_classes = V4.fault_classes
    pinned = staticmethod(pinned_episodes)


class AttitudeFTCv4Env(BatchEnv):
    """One whole ``scftc-v4`` episode per ``reset`` (v3's environment on v4's draws)."""

    batch_type = V4MissionBatch


class AttitudeFTCv4VectorEnv(BatchVectorEnv):
    """``num_envs`` ``scftc-v4`` episodes stepped as one call of the fused kernel."""

    batch_type = V4MissionBatch
