"""``scftc-v3``'s tuners (train split only): what each tunable port is tuned over (``tuning.py``)."""
