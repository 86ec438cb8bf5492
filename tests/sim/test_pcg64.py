"""``sim/pcg64.py`` draws numpy's own numbers: PCG64's stream and the ziggurat's normals, its rare
branches included, and leaves the states where numpy's generators leave them."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.sim import pcg64


def _generators(n: int) -> list[np.random.Generator]:
    return [np.random.Generator(np.random.PCG64(np.random.SeedSequence([e, 2024, 7]))) for e in range(n)]


def test_normals_are_numpys_to_the_bit_tails_included():
    generators = _generators(64)
    for generator in generators:
        generator.uniform(size=3)  # a stream already drawn from (as the sensors' gyro bias does)
    states = pcg64.states_of(generators)
    drawn = np.empty((64, 40_000))
    pcg64.fill_standard_normal(states, drawn)
    expected = np.stack([generator.standard_normal(40_000) for generator in generators])
    np.testing.assert_array_equal(drawn, expected)
    np.testing.assert_array_equal(states, pcg64.states_of(generators))  # same place in the stream
    # not vacuous: the ziggurat's slow paths (wedges, and the tail beyond r) were taken
    assert np.sum(np.abs(expected) > 3.6541528853610088) > 50


def test_fill_continues_where_it_stopped():
    generators = _generators(3)
    states = pcg64.states_of(generators)
    first, second = np.empty((3, 5)), np.empty((3, 7))
    pcg64.fill_standard_normal(states, first)
    pcg64.fill_standard_normal(states, second)
    expected = np.stack([generator.standard_normal(12) for generator in generators])
    np.testing.assert_array_equal(np.concatenate([first, second], axis=1), expected)


def test_only_pcg64_streams_are_taken():
    with pytest.raises(ValueError, match="PCG64"):
        pcg64.states_of([np.random.Generator(np.random.MT19937(0))])
