"""``e2e_ppo`` on ``scftc-v4``: v3's end-to-end recurrent policy (``versions/v3/controllers/ppo.py``:
an LSTM over the 26 scaled readings and the previous action, one tanh layer, a linear head for the
four wheels and three rods), the same layout and input scaling, its weights trained on v4's train
split (``training/ppo.py``): ``weights/e2e_ppo.npz`` of this version with its ``.yaml``. It reports
no diagnosis.
"""

from __future__ import annotations

from scftc_cli.versions.v3.controllers import ppo as v3
from scftc_cli.versions.v4.spec import V4

OBS_SCALE = v3.OBS_SCALE


class E2EPPO(v3.E2EPPO):
    benchmark = V4.version
