"""The same numbers however the numerical libraries were loaded (docs/numerics.md).

The same evaluation runs (a) as the ``scftc`` command, (b) with another OpenBLAS kernel, (c) from a
process that imported numpy before the package and (d) with numpy's loops for other CPU features,
and must print the same JSON; and every built-in's golden digests, recomputed under (b), (c) and
(d), must be the committed ones. The package pins no kernel (numpy and OpenBLAS pick theirs by
CPU), so (b) forces OpenBLAS's Sandybridge kernel and (d) takes away numpy's AVX-512 loops (on a CPU
without AVX-512, its AVX2 ones).

``KNOWN`` lists the built-ins whose arithmetic is not yet the project's own, with the reason: none
since numerics epoch 2. Only their digests may differ, and only they.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.golden.digests import golden_path

REPO = Path(__file__).resolve().parents[2]

KNOWN: dict[tuple[str, str], str] = {}


def _avx512() -> bool:
    try:
        return "avx512f" in Path("/proc/cpuinfo").read_text()
    except OSError:
        return False


OTHER_KERNEL = "Sandybridge"
OTHER_LOOPS = "X86_V4 AVX512_ICL AVX512_SPR" if _avx512() else "X86_V3"
VARIANTS = {
    "cli": ({}, False),
    "openblas-kernel": ({"OPENBLAS_CORETYPE": OTHER_KERNEL}, False),
    "numpy-first": ({}, True),
    "numpy-loops": ({"NPY_DISABLE_CPU_FEATURES": OTHER_LOOPS}, False),
}
EVAL = ["eval", "--benchmark", "scftc-v3", "--controller", "rls_dob", "--class", "all"]
EVAL += ["--n-faults", "2", "--n-seeds", "1", "--format", "json"]


def _environment(extra: dict[str, str]) -> dict[str, str]:
    base = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES")}
    return {**base, **extra}


def _python(code: str, numpy_first: bool, extra: dict[str, str]) -> str:
    prelude = "import numpy\n" if numpy_first else ""
    out = subprocess.run(
        [sys.executable, "-c", prelude + code],
        capture_output=True,
        text=True,
        env=_environment(extra),
        cwd=REPO,
        timeout=900,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout


def _without_timings(document: object) -> object:
    if isinstance(document, dict):
        return {k: _without_timings(v) for k, v in document.items() if "second" not in k and "time" not in k}
    if isinstance(document, list):
        return [_without_timings(v) for v in document]
    return document


def _eval_json(variant: str) -> object:
    extra, numpy_first = VARIANTS[variant]
    if variant == "cli":
        scftc = Path(sys.executable).with_name("scftc")
        out = subprocess.run(
            [str(scftc), *EVAL], capture_output=True, text=True, env=_environment(extra), timeout=900
        )
        assert out.returncode == 0, out.stderr[-2000:]
        stdout = out.stdout
    else:
        code = f"import sys\nsys.argv = ['scftc', *{EVAL!r}]\nfrom scftc_cli.commands.app import main\nmain()"
        stdout = _python(code, numpy_first, extra)
    return _without_timings(json.loads(stdout))


@pytest.mark.slow
def test_an_evaluation_prints_the_same_json_however_the_libraries_load():
    reference = _eval_json("cli")
    for variant in ("openblas-kernel", "numpy-first", "numpy-loops"):
        assert _eval_json(variant) == reference, f"{variant}: the JSON differs from the command's"


@pytest.mark.slow
@pytest.mark.parametrize("variant", ["openblas-kernel", "numpy-first", "numpy-loops"])
def test_every_builtin_flies_its_golden_bits_however_the_libraries_load(variant):
    extra, numpy_first = VARIANTS[variant]
    code = (
        "import json\nfrom tests.golden.digests import version_digests\n"
        "from scftc_cli.versions import published_names\n"
        "print(json.dumps({v: version_digests(v)['digests'] for v in published_names()}))"
    )
    flown = json.loads(_python(code, numpy_first, extra))
    moved = set()
    for version, controllers in flown.items():
        committed = json.loads(golden_path(version).read_text())["digests"]
        for name, cells in controllers.items():
            if cells != committed[name]:
                moved.add((version, name))
    unexplained = moved - set(KNOWN)
    assert not unexplained, f"{variant}: digests moved for {sorted(unexplained)}"
