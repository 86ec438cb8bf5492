"""The same floating-point kernels on every x86-64 machine (``scftc_cli.PINNED_NUMERICS``): importing
the package pins OpenBLAS's and numpy's kernel choice before numpy loads, the sandboxed child gets
the same pins, and a value the user set is kept."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from scftc_cli import PINNED_NUMERICS

pytestmark = pytest.mark.skipif(not PINNED_NUMERICS, reason="the pins are for x86-64 machines")
PROBE = (
    "import os, json, scftc_cli, numpy\n"
    "print(json.dumps({k: os.environ.get(k) for k in scftc_cli.PINNED_NUMERICS}))"
)


def _probe(env: dict[str, str]) -> dict[str, str]:
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, check=True)
    return json.loads(out.stdout)


def test_importing_the_package_pins_the_kernels_and_keeps_a_users_choice():
    clean = {k: v for k, v in os.environ.items() if k not in PINNED_NUMERICS}
    assert _probe(clean) == PINNED_NUMERICS
    assert _probe({**clean, "OPENBLAS_CORETYPE": "Sandybridge"})["OPENBLAS_CORETYPE"] == "Sandybridge"


def test_the_sandboxed_child_gets_the_same_pins():
    from scftc_cli.submission.isolation import bwrap_argv

    argv = bwrap_argv(
        source_fd=3, source_path="/submission/x.py", seccomp_fd=4, info_fd=5, command=["python"]
    )
    pairs = {argv[i + 1]: argv[i + 2] for i, a in enumerate(argv) if a == "--setenv"}
    for name, value in PINNED_NUMERICS.items():
        assert pairs[name] == os.environ.get(name, value)


WIDE_PROBE = (
    "import json, scftc_cli\n"
    "expected = scftc_cli.wide_vector_features()\n"
    "from numba.core.registry import cpu_target\n"
    "print(json.dumps([expected, cpu_target.target_context.codegen()._tm_features]))"
)


def _wide_probe(env: dict[str, str]) -> tuple[str | None, str]:
    out = subprocess.run(
        [sys.executable, "-c", WIDE_PROBE], capture_output=True, text=True, env=env, check=True
    )
    expected, compiled = json.loads(out.stdout)
    return expected, compiled


def test_numba_compiles_wide_vectors_on_avx512_and_keeps_a_users_choice():
    """Where the CPU has AVX-512, numba compiles with the host's features and 512-bit vectors
    preferred (``scftc_cli.WIDE_VECTORS``); elsewhere, or where the user set numba's CPU, numba's
    own choice stands."""
    from scftc_cli import WIDE_VECTORS

    clean = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_CPU")}
    avx512, compiled = _wide_probe(clean)
    if avx512 is not None:
        assert compiled == avx512 and compiled.endswith("," + WIDE_VECTORS)
    else:
        assert WIDE_VECTORS not in compiled
    mine = compiled.replace("," + WIDE_VECTORS, "")
    assert _wide_probe({**clean, "NUMBA_CPU_FEATURES": mine})[1] == mine


@pytest.mark.slow
def test_the_vector_width_changes_no_bit_of_the_networks():
    """The pinned network bits (``test_kernel_bits_are_pinned``) hold with numba's own 256-bit
    vectors too (on a CPU without AVX-512 both runs compile the same code)."""
    clean = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_CPU")}
    _, compiled = _wide_probe(clean)
    narrow = compiled.replace(",-prefer-256-bit", "")
    test = "tests/baselines/test_inference.py::test_kernel_bits_are_pinned"
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", test],
        capture_output=True, text=True, env={**clean, "NUMBA_CPU_FEATURES": narrow},
    )  # fmt: skip
    assert run.returncode == 0, run.stdout[-2000:]
