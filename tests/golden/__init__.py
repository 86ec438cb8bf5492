"""The golden digests (``digests.py``): the committed bits of every built-in."""

import scftc_cli  # noqa: F401  (the package's numerical settings apply before numpy loads)
