"""Readable numpy forms of the compiled kernels: oracles for the tests, never a production path."""
