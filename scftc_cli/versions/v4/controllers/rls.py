"""``rls_dob`` on ``scftc-v4``: v3's estimate-then-control port (``versions/v3/controllers/rls.py``:
v2's per-wheel RLS and disturbance observer on the mission law), its settings tuned on v4's train
split, starting from v3's."""

from __future__ import annotations

from scftc_cli.versions.v3.controllers import rls as v3
from scftc_cli.versions.v4.spec import V4

NAME = v3.NAME


class RLSDob(v3.RLSDob):
    """v3's ``rls_dob``, with v4's committed parameters (``params/rls_dob.yaml`` of this version)."""

    tuned_as = (NAME, V4.version)
