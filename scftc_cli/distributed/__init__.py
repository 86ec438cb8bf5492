"""Spreading evaluation over a Dask cluster (``scftc[dask]``): controller references a worker can
rebuild (``refs``), the chunked tasks and the runner that maps them (``runner``).

Without ``--workers``/``--scheduler`` nothing here is imported and everything runs in process.
"""
