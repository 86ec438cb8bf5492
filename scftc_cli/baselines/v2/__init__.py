"""``scftc-v2``'s built-in controllers: the shared analytic law (``law``) and its ports."""
