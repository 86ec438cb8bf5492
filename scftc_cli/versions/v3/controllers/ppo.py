"""``e2e_ppo`` on ``scftc-v3``: one recurrent network that must fuse the sensors, follow the mission's
targets, identify the faults, allocate the four wheels and unload them with the three rods at once.

Trained from scratch with PPO on the train split of ``scftc/AttitudeFTC-v3`` (``training/ppo.py``:
the batched recurrent PPO v2's ``e2e_ppo`` was trained with, ``training/recurrent_ppo.py``), in the
actor layout the shared deployed form runs (``baselines/policy.py``): an LSTM over the scaled
observation and the previous action, one tanh layer, a linear action head. It reports no
diagnosis (``health`` returns ``None``: scored as never alarming).

Weights: ``weights/e2e_ppo.npz`` of this version's folder, with a sidecar ``e2e_ppo.yaml``.
"""

from __future__ import annotations

from scftc_cli.baselines import policy
from scftc_cli.protocol import Context
from scftc_cli.versions.v3.controllers.law import rods_of
from scftc_cli.versions.v3.spec import V3, AgilePlant

ACTIONS = V3.action_dim
assert isinstance(V3.plant, AgilePlant)
WINDOW_S = V3.plant.window_steps * V3.plant.dt_s
SENSORS = (1.0,) * 12 + (20.0,) * 3 + (1.0 / 600.0,) * 4  # v2's 19 readings, scaled as v2's policy
OBS_SCALE = SENSORS + (2e4,) * 3 + (1.0,) * 3 + (1.0 / WINDOW_S,) + (1.0,) * ACTIONS
"""The policy's input: [3 head MRPs, 3 validity flags, 20 x gyro, tachometers / 600 rad/s,
2e4 x the magnetometer (a field of up to ~6e-5 T to order 1), the target MRP, the time left over
the window's length, previous action (four wheels, three rods)]."""


class E2EPPO(policy.E2EPPO):
    obs_scale = OBS_SCALE
    benchmark = V3.version

    def reset(self, n: int, context: Context) -> None:
        rods_of(context)  # a clear error on a version without wheels and rods
        super().reset(n, context)
