"""The study: the battery and sensor tables (``run``, ``tables``), their figures (``figures``),
and the cross-check of the default backend against Basilisk (``crosscheck``)."""
