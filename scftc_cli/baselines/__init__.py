"""The controller battery. Importing this package registers every built-in controller, in the
order of the battery table (SPEC section 4): fault-unaware, classical, learned, beyond the study,
then the privileged oracles (``registry()`` lists those last)."""

# ruff: noqa: I001  (the import order is the battery order)

from scftc_cli.baselines import (  # noqa: F401  (imported to register)
    analytic,
    pid,
    adaptive,
    icl,
    nussbaum,
    ppo,
    rma,
    rls,
)
