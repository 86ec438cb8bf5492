"""The built-in controller battery, one module per method (``scftc_cli/registry.py`` lists them).

Shared pieces: ``analytic`` (the analytic law), ``observer`` (measured torque, disturbance
observer, dither), ``params`` (tuned parameters and weights on disk), ``checker`` (the protocol
check every controller passes).
"""
