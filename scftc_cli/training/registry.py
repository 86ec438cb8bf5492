"""Imports every trainer module so that each registers itself (one line per module)."""

from scftc_cli.training import (
    ppo,  # noqa: F401  (e2e_ppo; sb3-contrib imported only when run)
    rma,  # noqa: F401  (rma_student, rma_dob)
    tuning,  # noqa: F401  (the classical battery)
)
