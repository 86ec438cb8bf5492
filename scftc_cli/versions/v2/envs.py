"""``scftc/AttitudeFTC-v2``: ``scftc-v2``'s reaction-wheel plant, sensors and fault taxonomy as a
gymnasium environment.

An episode is one ``scftc-v2`` episode (docs/benchmark-v2.md): a fault drawn from the chosen split,
actuator classes and sensor classes by ``sim.faults.sample_episodes_batch`` (the pinned draws'
distribution), starting mid-flight at its onset; 400 steps of 0.5 s, then truncation. The agent
observes exactly what a benchmark controller observes, the 19 values of ``HeadsGyroTachometers``
(three star-tracker heads as MRPs, their validity flags, the gyro, four tachometers; optionally
with its previous action appended), and commands four normalized motor torques in [-1, 1]; the
fault is never part of the observation or of ``info``. The reward is shaped on the *measured*
state: ``e`` the principal angle of the fused attitude (``controllers.law.AttitudeFuser``: the
median of the valid heads, propagated with the gyro through an outage) and ``w`` the gyro reading,

    r = -e_deg / 180 - |w| + 0.5 exp(-e_deg / 1 deg)

(``scftc/AttitudeFTC-v1``'s shape); ``info["pointing_error_deg"]`` reports the *true* error, for
logging only.

``AttitudeFTCv2Env`` is the single-episode ``gymnasium.Env`` (passes ``check_env``);
``AttitudeFTCv2VectorEnv`` steps ``num_envs`` episodes as one call of the fused wheel kernel
(``backend="numpy"``; same-step autoreset as v1's: every episode shares the fixed horizon, so they
reset together and the last observation is in ``info["final_obs"]``). Observations are float32 by
default (``dtype=np.float64``: the benchmark's values to the bit). ``reset(options={"episodes":
e})`` flies the given ``WheelEpisodes`` (as many as environments) instead of drawing new ones.
Train only on the ``train`` split; the ``test`` split exists here for evaluation, never for tuning.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from scftc_cli.envs.batch import BatchEnv, BatchVectorEnv, EpisodeBatch
from scftc_cli.versions.v2.sim.faults import WheelEpisodes, sample_episodes_batch
from scftc_cli.versions.v2.sim.testbed import CONSTANTS, TESTBED
from scftc_cli.versions.v2.spec import V2

ENV_ID = "scftc/AttitudeFTC-v2"
"""The suffix is the benchmark version. Gymnasium reads it as a newer version of
``AttitudeFTC-v1`` and would warn v1 users that v1 "is out of date"; scftc-v2 is another track,
so registering the ids silences that one warning (``envs/__init__.py``)."""
DEFAULT_CLASSES: tuple[str, ...] = V2.fault_classes
DEFAULT_SENSORS: tuple[str | None, ...] = (None,)
ACTION_DIM = V2.action_dim
# Bounds no episode can reach. The wheels' torques are internal, so the total momentum keeps its
# initial size (<= ~2.1 N m s: hub rates <= 0.035 rad/s, wheels <= 1000 rpm); the motor cannot
# spin a wheel past Omega_max by more than one step (u_max dt / Js ~ 16 rad/s), so
# |Omega| < 1.1 Omega_max and |w| <= (2.1 + Js |G| |Omega|) / (0.7 * 6 kg m^2) < 2 rad/s.
GYRO_BOUND_RAD_S = 10.0
TACHOMETER_BOUND_RAD_S = 2.0 * CONSTANTS.omega_max_rad_s


class WheelBatch(EpisodeBatch):
    """``n`` ``scftc-v2`` episodes flown together (``EpisodeBatch``); the reward reads the fused
    attitude itself (the target is the origin)."""

    spec = V2
    testbed = TESTBED
    episodes_type = WheelEpisodes
    default_classes = DEFAULT_CLASSES
    default_sensors = DEFAULT_SENSORS

    @classmethod
    def observation_space(cls, include_prev_action: bool, dtype: type) -> spaces.Box:
        heads = V2.sensors.star_tracker_heads if V2.sensors else 0
        low = (
            [-1.0] * 3 * heads  # MRPs on the shadow-switched branch: |sigma| <= 1
            + [0.0] * heads
            + [-GYRO_BOUND_RAD_S] * 3
            + [-TACHOMETER_BOUND_RAD_S] * CONSTANTS.n_wheels
            + ([-1.0] * ACTION_DIM if include_prev_action else [])
        )
        low_arr: np.ndarray = np.array(low, dtype=dtype)
        high_arr = -low_arr
        high_arr[3 * heads : 4 * heads] = 1.0
        return spaces.Box(low_arr, high_arr, dtype=dtype)

    def draw(self, rng: np.random.Generator) -> WheelEpisodes:
        return sample_episodes_batch(rng, self.n, self.split, self.fault_classes, self.sensor_faults)

    def measured_error(self, obs: np.ndarray, fused_sigma: np.ndarray) -> np.ndarray:
        return fused_sigma


class AttitudeFTCv2Env(BatchEnv):
    """One ``scftc-v2`` episode per ``reset`` (see the module docstring and ``BatchEnv``; the
    default classes are all five actuator classes)."""

    batch_type = WheelBatch


class AttitudeFTCv2VectorEnv(BatchVectorEnv):
    """``num_envs`` ``scftc-v2`` episodes stepped as one call of the fused kernel (same-step
    autoreset; ``BatchVectorEnv``)."""

    batch_type = WheelBatch
