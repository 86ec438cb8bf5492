"""``pid`` on ``scftc-v4``: v3's fault-unaware mission law with integral action
(``versions/v3/controllers/pid.py``), its five settings tuned on v4's train split."""

from __future__ import annotations

from scftc_cli.versions.v3.controllers import pid as v3
from scftc_cli.versions.v4.spec import V4

NAME = v3.NAME


class PID(v3.PID):
    """v3's ``pid``, with v4's committed parameters (``params/pid.yaml`` of this version)."""

    tuned_as = (NAME, V4.version)
