"""The written definition keeps up with the code, and the repository stands alone.

* Every value of every registered version's spec appears in its definition (``Version.definition``;
  ``docs/benchmark.md`` for ``scftc-v1``): the spec object is walked
  generically (a new field is covered the day it is added) and each leaf must have a row in the
  document's table "The spec as data", keyed by its dotted path, whose value cell shows the value
  the way the document writes numbers (``0.2``, ``2.3``, ``400``; ``2`` or ``2.0``; an interval with
  its open and closed ends, ``[0.7, 0.8) U (2.0, 2.3]``; the confidence as ``95 %``). The prose must
  name every number too, and every sensor fault's angle in degrees.
* The reference re-implementation of the draws printed in ``docs/benchmark.md`` gives exactly the
  simulator's episodes.
* No file under ``README.md``, ``docs/`` or ``scftc_cli/`` points outside the repository to the
  working notes the benchmark was first written from.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from itertools import product
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import BaseModel

from scftc_cli.spec import BenchmarkSpec, Interval, IntervalSet
from scftc_cli.versions import all_versions
from scftc_cli.versions.v1.sim.testbed import TESTBED as V1_TESTBED
from scftc_cli.versions.v1.spec import V1
from scftc_cli.versions.v2.sim.testbed import TESTBED as V2_TESTBED
from scftc_cli.versions.v2.spec import V2

ROOT = Path(__file__).resolve().parents[1]
BENCHMARK_MD = ROOT / "docs" / "benchmark.md"
BENCHMARK_V2_MD = ROOT / "docs" / "benchmark-v2.md"
TABLE_HEADING = "## 12. The spec as data"
DEFINITIONS = {  # each registered version's spec, its written definition and the heading of its spec table
    v.name: (v.spec, ROOT / v.definition[0], v.definition[1]) for v in all_versions()
}
FORBIDDEN = ("../shared", "shared/SPEC", "CONTROLLERS.md", "SPEC.md", "SPEC section", "SPEC-v2")
BINARY_SUFFIXES = {".png", ".svg", ".pt", ".pyc", ".pdf", ".npz", ".npy", ".gz", ".zip"}


def number_forms(x: float | int) -> set[str]:
    """The ways the document may write ``x``: ``0.2``, ``400``; an integral float as ``2`` or ``2.0``."""
    if isinstance(x, bool):
        return {str(x).lower()}
    forms = {f"{x:g}"}
    if isinstance(x, float) and x.is_integer():
        forms.add(f"{x:.1f}")
    return forms


def interval_forms(part: Interval) -> set[str]:
    """``[0.7, 0.8)`` and its spellings: open and closed ends are part of the text."""
    left, right = ("[" if part.lo_closed else "("), ("]" if part.hi_closed else ")")
    return {f"{left}{lo}, {hi}{right}" for lo, hi in product(number_forms(part.lo), number_forms(part.hi))}


def leaves(value: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    """``(dotted path, value)`` of every leaf of a spec; an interval (set) is one leaf."""
    if isinstance(value, IntervalSet | Interval):
        yield path, value
    elif isinstance(value, BaseModel):
        for name in type(value).model_fields:
            yield from leaves(getattr(value, name), f"{path}.{name}" if path else name)
    elif isinstance(value, dict):
        for key, item in value.items():
            yield from leaves(item, f"{path}.{key}")
    elif isinstance(value, tuple) and any(isinstance(v, BaseModel) for v in value):
        for i, item in enumerate(value):
            yield from leaves(item, f"{path}[{i}]")
    else:
        yield path, value


def expected_texts(path: str, value: Any) -> list[set[str]]:
    """What the value cell of ``path``'s row must contain: each set lists acceptable spellings of
    one piece, and every piece must be present."""
    if isinstance(value, Interval):
        value = IntervalSet(parts=(value,))
    if isinstance(value, IntervalSet):
        return [
            {
                sep.join(combo)
                for sep in (" U ", " ∪ ")
                for combo in product(*(sorted(interval_forms(p)) for p in value.parts))
            }
        ]
    if path.endswith("confidence"):
        return [{f"{100 * value:g} %"}]
    if isinstance(value, tuple):
        return [expected_texts(path, v)[0] for v in value]
    if isinstance(value, str):
        return [{value}]
    if value is None:
        return [{"none"}]
    return [number_forms(value)]


def contains_number(text: str, form: str) -> bool:
    """``form`` occurs in ``text`` as a whole number (``0.2`` not inside ``0.25`` or ``10.2``)."""
    if not re.fullmatch(r"-?\d+(\.\d+)?", form):
        return form in text
    return re.search(rf"(?<![\w.]){re.escape(form)}(?!\.?\d)", text) is not None


def spec_table(doc: str, heading: str = TABLE_HEADING) -> dict[str, str]:
    """Rows ``| `path` | value | ... |`` of the section "The spec as data", by path."""
    assert heading in doc, f"the definition lacks the section {heading!r}"
    section = doc.split(heading, 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        m = re.match(r"\|\s*`([^`]+)`\s*\|([^|]*)\|", line)
        if m:
            rows[m.group(1)] = m.group(2)
    return rows


@pytest.mark.parametrize("version", DEFINITIONS)
def test_every_value_of_the_spec_is_in_the_benchmark_definition(version: str) -> None:
    spec, path_md, heading = DEFINITIONS[version]
    doc = path_md.read_text()
    rows = spec_table(doc, heading)
    prose = doc.split(heading, 1)[0]
    problems = []
    for path, value in leaves(spec):
        if path not in rows:
            problems.append(f"no row for `{path}` (value {value}) in {heading!r}")
            continue
        for forms in expected_texts(path, value):
            if not any(contains_number(rows[path], f) for f in forms):
                problems.append(f"row `{path}` does not show {sorted(forms)[0]!r}")
            if not isinstance(value, str | bool | None) and not any(contains_number(prose, f) for f in forms):
                problems.append(f"the prose never writes {sorted(forms)[0]!r} (`{path}`)")
    for fault in spec.sensor_faults:
        if fault.startswith("bias_"):
            angle = fault.removeprefix("bias_")
            if not re.search(rf"(?<![\w.]){re.escape(angle)} deg\b", prose):
                problems.append(f"the prose never gives the angle of `{fault}` as '{angle} deg'")
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("spec", [d[0] for d in DEFINITIONS.values()], ids=lambda s: s.version)
def test_the_walk_reaches_every_field(spec: BenchmarkSpec) -> None:
    paths = {p for p, _ in leaves(spec)}
    for name in type(spec).model_fields:
        assert any(p == name or p.startswith((f"{name}.", f"{name}[")) for p in paths), name
    assert "splits.test.gain_magnitude" in paths and "gates.dwell_steps" in paths
    assert expected_texts("splits.test.bias", spec.splits["test"].bias)[0] >= {"[-0.3, -0.2) U (0.2, 0.3]"}


def _reference_code(doc: str) -> str:
    blocks = re.findall(r"```python\n(.*?)```", doc, flags=re.S)
    chosen = [b for b in blocks if "def rng_for" in b]
    assert len(chosen) == 1, "a definition must hold exactly one reference draw listing"
    return chosen[0]


def test_the_reference_draw_in_the_definition_gives_the_simulators_episodes() -> None:
    ns: dict[str, Any] = {}
    exec(compile(_reference_code(BENCHMARK_MD.read_text()), "docs/benchmark.md", "exec"), ns)
    n_faults, n_seeds = 6, 3
    for salt, split, cls in product((b"", bytes(range(32))), ("train", "test"), V1.fault_classes):
        e = V1_TESTBED.draw(split, cls, None, n_faults, n_seeds, salt)
        for i, j in product(range(n_faults), range(n_seeds)):
            k = i * n_seeds + j
            g, b, f = ns["fault"](split, cls, i, salt)
            sigma0, omega0 = ns["initial_state"](split, cls, i, j, salt)
            assert np.array_equal(g, e.fault.gain[k]) and np.array_equal(b, e.fault.bias[k])
            assert f == e.fault.inertia_scale[k]
            assert np.array_equal(sigma0, e.sigma0[k]) and np.array_equal(omega0, e.omega0_rad_s[k])
    for split, fault in product(("train", "test"), V1.sensor_faults):
        angle_deg = V1.sensor_class(fault).angle_deg
        if angle_deg is None:
            continue
        e = V1_TESTBED.draw(split, V1.sensor_base_class, fault, n_faults, n_seeds)
        assert e.sensor_bias_mrp is not None
        for i, j in product(range(n_faults), range(n_seeds)):
            mrp = ns["attitude_bias_mrp"](split, i, j, angle_deg)
            assert np.array_equal(mrp, e.sensor_bias_mrp[i * n_seeds + j])


def _text_files() -> Iterator[Path]:
    yield ROOT / "README.md"
    for top in ("docs", "scftc_cli"):
        for path in sorted((ROOT / top).rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts and path.suffix not in BINARY_SUFFIXES:
                yield path


@pytest.mark.parametrize("needle", FORBIDDEN)
def test_nothing_points_outside_the_repository(needle: str) -> None:
    hits = []
    for path in _text_files():
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            continue
        for n, line in enumerate(text.splitlines(), 1):
            if needle in line:
                hits.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()[:100]}")
    assert not hits, f"{needle!r} must not appear (the repository stands alone):\n" + "\n".join(hits)


def test_the_reference_draw_of_v2_gives_the_simulators_episodes() -> None:
    ns: dict[str, Any] = {}
    exec(compile(_reference_code(BENCHMARK_V2_MD.read_text()), "docs/benchmark-v2.md", "exec"), ns)
    n_faults, n_seeds = 5, 2
    for salt, split in product((b"", bytes(range(32))), ("train", "test")):
        for cls in V2.fault_classes:
            e = V2_TESTBED.draw(split, cls, None, n_faults, n_seeds, salt)
            for i, j in product(range(n_faults), range(n_seeds)):
                k = i * n_seeds + j
                g, b, m, f, onset = ns["fault"](split, cls, i, salt)
                assert np.array_equal(g, e.fault.gain[k]) and np.array_equal(b, e.fault.bias[k])
                assert np.array_equal(m, e.fault.friction_multiplier[k])
                assert f == e.fault.inertia_scale[k] and onset == e.fault.onset_step[k]
                sigma0, omega0, wheels = ns["initial_state"](split, cls, i, j, salt)
                assert np.array_equal(sigma0, e.sigma0[k]) and np.array_equal(omega0, e.omega0_rad_s[k])
                assert np.array_equal(wheels, e.wheel_speed0_rad_s[k])
                stream = ns["noise_stream"](split, cls, i, j, salt)
                mine = np.random.Generator(np.random.PCG64(np.random.SeedSequence(e.noise_seed[k].tolist())))
                assert np.array_equal(stream.random(8), mine.random(8))
        for sensor in V2.sensor_faults:
            e = V2_TESTBED.draw(split, V2.sensor_base_class, sensor, n_faults, n_seeds, salt)
            for i, j in product(range(n_faults), range(n_seeds)):
                k = i * n_seeds + j
                head, bias, step = ns["sensor_fault"](split, sensor, i, j, salt)
                assert head == e.sensor_fault.head[k]
                assert np.array_equal(bias, e.sensor_fault.head_bias_mrp[k])
                assert np.array_equal(step, e.sensor_fault.gyro_bias_step_rad_s[k])
