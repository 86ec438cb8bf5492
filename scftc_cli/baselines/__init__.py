"""The controller battery. Importing this package registers every built-in controller."""

from scftc_cli.baselines import analytic  # noqa: F401
