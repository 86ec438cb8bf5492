"""Result records: what lands on disk and on stdout.

``CellResult`` and ``EvalResult`` are the JSON contract of ``scftc eval --format json``;
``EpisodeOutcomes`` holds a cell's per-episode outcomes (arrays) for paired comparisons and
per-episode logs; ``RunProvenance`` says what code, libraries and artifacts produced a result.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    model_serializer,
    model_validator,
)
from pydantic.json_schema import SkipJsonSchema

from scftc_cli.spec import GATES

BY_FAULT_FIELDS = ("by_fault", "interval_by_fault", "design_effect")


class GateStat(BaseModel):
    """Episodes passing one gate: ``k`` of the cell's ``n``, the rate and its Wilson interval; and,
    where the cell's fault of each episode is known, the counts per fault with the by-fault
    interval and design effect computed from them (``scftc_cli/statistics.py``; docs/statistics.md).

    A record without per-fault counts (one written before they existed, or a cell that is not a
    whole faults x seeds design) has the three by-fault fields ``None`` and serializes without
    them, exactly as before.
    """

    k: int = Field(ge=0)
    rate: float = Field(ge=0, le=1)
    ci_low: float = Field(ge=0, le=1)
    ci_high: float = Field(ge=0, le=1)
    by_fault: list[int] | None = Field(
        default=None,
        description="Passing episodes of each fault, in fault order; each fault holds n / len(by_fault) "
        "episodes (its initial conditions). What interval_by_fault and design_effect are computed from.",
    )
    interval_by_fault: tuple[float, float] | None = Field(
        default=None,
        description="By-fault 95 % interval [low, high] of the rate: the percentile interval of the exact "
        "cluster bootstrap over faults, never narrower than Wilson's; at k = 0 or k = n the Wilson interval "
        "of 0 or all of the faults (docs/statistics.md).",
    )
    design_effect: float | None = Field(
        default=None,
        description="Variance of the rate under fault clustering over the binomial p (1 - p) / n; null "
        "when k = 0 or k = n.",
    )

    @model_validator(mode="after")
    def _counts_add_up(self) -> GateStat:
        if self.by_fault is not None and (sum(self.by_fault) != self.k or min(self.by_fault, default=0) < 0):
            raise ValueError(f"by_fault {self.by_fault} does not add up to k = {self.k}")
        if self.interval_by_fault is not None:
            low, high = self.interval_by_fault
            if not 0 <= low <= high <= 1:
                raise ValueError(f"interval_by_fault {self.interval_by_fault} is not inside [0, 1]")
        return self

    @model_serializer(mode="wrap")
    def _omit_absent_by_fault(self, handler: SerializerFunctionWrapHandler) -> dict:
        data = handler(self)
        if all(getattr(self, name) is None for name in BY_FAULT_FIELDS):
            for name in BY_FAULT_FIELDS:
                data.pop(name, None)
        return data


class FinalError(BaseModel):
    """The final true pointing error of a cell's episodes (deg): median, mean and, where recorded,
    the cell's final-error profile: ``profile[i]`` episodes end within ``PROFILE_TAUS_DEG[i]``
    (``statistics.profile_counts``; 40 log-spaced thresholds from 0.01 to 180 deg). One instant,
    not the ranked gate: the profile of the gate is ``SettledProfile``; this one stays because
    every record holds it (the only profile of records older than ``SettledProfile``) and
    ``leaderboard verify`` checks it."""

    median: float
    mean: float
    profile: list[int] | None = Field(
        default=None, description="Episodes whose final error is <= each threshold of PROFILE_TAUS_DEG."
    )

    @model_serializer(mode="wrap")
    def _omit_absent_profile(self, handler: SerializerFunctionWrapHandler) -> dict:
        data = handler(self)
        if self.profile is None:
            data.pop("profile", None)
        return data


class SettledProfile(BaseModel):
    """The ranked gate read at every tolerance: ``k[i]`` of the cell's ``n`` episodes kept their
    largest error over the final dwell of every pointing window within ``taus[i]`` deg, i.e. would
    have settled had the settled tolerance been ``taus[i]`` (the dwell unchanged). ``taus`` is the
    version's grid ``scoring.settled_profile_taus(spec.gates)``: ``PROFILE_TAUS_DEG`` with the
    settled and operational tolerances inserted, so that ``k`` there is exactly the cell's settled
    and operational ``k`` (docs/statistics.md).

    A record written before this existed has none (``CellResult.settled_profile`` ``None``): the
    per-episode errors it would be derived from are not stored, so it is shown as unavailable.
    """

    k: list[int] = Field(
        description="Episodes whose largest error over every window's final dwell is <= each threshold "
        "of the version's settled-profile grid (PROFILE_TAUS_DEG with the settled and operational "
        "tolerances inserted); non-decreasing."
    )
    interval_by_fault: list[tuple[float, float]] | None = Field(
        default=None,
        description="By-fault 95 % interval [low, high] of k[i] / n at each threshold (interval_by_fault "
        "over the per-fault counts there, which are not stored): the band around the profile.",
    )

    @model_validator(mode="after")
    def _a_profile(self) -> SettledProfile:
        if self.k != sorted(self.k) or min(self.k, default=0) < 0:
            raise ValueError("settled_profile.k must be non-decreasing counts >= 0")
        bands = self.interval_by_fault
        if bands is not None and (
            len(bands) != len(self.k) or not all(0 <= low <= high <= 1 for low, high in bands)
        ):
            raise ValueError(
                "settled_profile.interval_by_fault must hold one [low, high] in [0, 1] per threshold"
            )
        return self

    @model_serializer(mode="wrap")
    def _omit_absent_band(self, handler: SerializerFunctionWrapHandler) -> dict:
        data = handler(self)
        if self.interval_by_fault is None:
            data.pop("interval_by_fault", None)
        return data


class DiagnosisByFault(BaseModel):
    """A cell's diagnosis counts per fault, in fault order (each fault holds ``n / len(faulted)``
    episodes, its initial conditions): what by-fault intervals and the diagnosis ranking's tie test
    are computed from (``DiagnosisStats``' counts of the same names, split by fault)."""

    faulted: list[int]
    detected: list[int]
    isolated: list[int]
    severity_right: list[int]
    healthy_episodes: list[int]
    false_alarm_episodes: list[int]
    false_isolation_episodes: list[int]

    @model_validator(mode="after")
    def _one_count_per_fault(self) -> DiagnosisByFault:
        counts = [getattr(self, name) for name in type(self).model_fields]
        if len({len(c) for c in counts}) != 1 or min(min(c, default=0) for c in counts) < 0:
            raise ValueError("by-fault diagnosis counts must hold one count >= 0 per fault of every quantity")
        return self


class DiagnosisStats(BaseModel):
    """What a controller's fault detection said over a cell, against the truth (versions that
    score a diagnosis). Counts, so that rates and intervals can be formed and pooled.

    Attributes:
        faulted: episodes with a fault; ``detected`` of them raised an alarm at or after the onset,
            ``delay_mean_s``/``delay_median_s`` after it (``None`` when none was detected).
        isolated: faulted episodes whose last report names exactly the faulted units (any
            severity); ``severity_right``: and gives each its right severity.
        healthy_episodes: episodes with healthy flight (all, unless a fault starts at step 0);
            ``false_alarm_episodes`` of them raised an alarm before any fault.
        healthy_hours, false_alarms: flight time before the onset (or the whole episode) and the
            alarms raised in it (rising edges): ``false_alarms / healthy_hours`` is the rate per hour.
        reported, false_isolation_episodes, by_fault: recorded under the ``faulted_unit`` rule only
            (``DiagnosisSpec.detection``; ``None`` and not serialized under ``any_alarm``): whether
            the controller returned any health report at all, the episodes (of all ``n``) in which
            some report named a unit the truth holds healthy, and every count per fault.
    """

    faulted: int = Field(ge=0)
    detected: int = Field(ge=0)
    delay_mean_s: float | None = None
    delay_median_s: float | None = None
    isolated: int = Field(ge=0)
    severity_right: int = Field(ge=0)
    healthy_episodes: int = Field(ge=0)
    false_alarm_episodes: int = Field(ge=0)
    healthy_hours: float = Field(ge=0)
    false_alarms: int = Field(ge=0)
    reported: bool | None = None
    false_isolation_episodes: int | None = Field(default=None, ge=0)
    by_fault: DiagnosisByFault | None = None

    @property
    def false_alarms_per_hour(self) -> float:
        return self.false_alarms / self.healthy_hours if self.healthy_hours else 0.0

    @model_validator(mode="after")
    def _by_fault_adds_up(self) -> DiagnosisStats:
        if self.by_fault is not None:
            for name in type(self.by_fault).model_fields:
                if sum(getattr(self.by_fault, name)) != (getattr(self, name) or 0):
                    raise ValueError(f"diagnosis by_fault.{name} does not add up to {name}")
        return self

    @model_serializer(mode="wrap")
    def _omit_unrecorded(self, handler: SerializerFunctionWrapHandler) -> dict:
        data = handler(self)
        for name in ("reported", "false_isolation_episodes", "by_fault"):
            if getattr(self, name) is None:
                data.pop(name, None)
        return data


class CellResult(BaseModel):
    """One cell (controller, split, class, sensor fault) scored on the true state."""

    model_config = ConfigDict(populate_by_name=True)

    split: str
    fault_class: str = Field(alias="class")
    sensor: str | None
    n: int = Field(gt=0)
    settled: GateStat
    operational: GateStat
    touch_once: GateStat
    final_error_deg: FinalError
    window_settled: list[int] | None = Field(
        default=None, description="Settled episodes in each pointing window (versions with several)."
    )
    diagnosis: DiagnosisStats | None = None
    settled_profile: SettledProfile | None = Field(
        default=None,
        description="The ranked gate's performance profile with its by-fault band (absent on records "
        "written before it existed).",
    )
    settled_margin_deg: SkipJsonSchema[list[float] | None] = Field(
        default=None,
        exclude=True,
        repr=False,
        description="Each episode's largest dwell error minus the settled threshold (deg), fault-major: "
        "kept in memory for the drift report of `leaderboard verify`, never written.",
    )

    @model_serializer(mode="wrap")
    def _omit_absent(self, handler: SerializerFunctionWrapHandler) -> dict:
        data = handler(self)
        for name in ("window_settled", "diagnosis", "settled_profile"):
            if getattr(self, name) is None:
                data.pop(name, None)
        return data

    @property
    def key(self) -> tuple[str, str, str | None]:
        return (self.split, self.fault_class, self.sensor)

    @property
    def label(self) -> str:
        """``gain_bias`` or ``sign+dropout``."""
        return self.fault_class if self.sensor is None else f"{self.fault_class}+{self.sensor}"


class RunProvenance(BaseModel):
    """What produced a result: enough to rerun it, or to see why a rerun differs."""

    package_version: str
    git_commit: str | None = Field(description="HEAD of the checkout the package ran from, if any.")
    git_dirty: bool | None = None
    python: str
    libraries: dict[str, str] = Field(description="numpy, numba, scipy, torch, bsk versions (installed).")
    artifacts: dict[str, str] = Field(
        default_factory=dict, description="sha256 of each parameter or weight file the controller loaded."
    )
    controller_file_sha256: str | None = Field(default=None, description="For a controller given as a file.")


class EvalResult(BaseModel):
    """The JSON document ``scftc eval --format json`` prints."""

    benchmark_version: str
    controller: str
    privileged: bool
    backend: str
    cells: list[CellResult]
    provenance: RunProvenance | None = None

    def dump(self) -> dict:
        return self.model_dump(mode="json", by_alias=True, exclude_none=False)


@dataclass(frozen=True)
class EpisodeDiagnosis:
    """Per-episode diagnosis of a batch, on a version that scores one: what the controller's health
    reports said against the truth (``sim.testbed.DiagnosisTruth``), all ``(n,)`` but the codes.

    Attributes:
        onset_step: the first faulty step (``steps`` for an episode with no fault).
        first_alarm_step: the first step any unit was reported not healthy (-1: never).
        delay_steps: steps from the onset to the first alarm at or after it (-1: never detected, or
            no fault).
        false_alarms: alarms raised before the onset (rising edges).
        final_codes, truth_codes: ``(n, units)`` the last report and the truth.
        false_isolation: ``(n,)`` bool, some report named a unit the truth holds healthy (the
            ``faulted_unit`` rule; ``None`` under ``any_alarm``).
        reported: whether the controller returned any health report (``faulted_unit`` rule;
            ``None`` under ``any_alarm``).
    """

    onset_step: np.ndarray
    first_alarm_step: np.ndarray
    delay_steps: np.ndarray
    false_alarms: np.ndarray
    final_codes: np.ndarray
    truth_codes: np.ndarray
    false_isolation: np.ndarray | None = None
    reported: bool | None = None

    @classmethod
    def concat(cls, parts: list[EpisodeDiagnosis]) -> EpisodeDiagnosis:
        """The diagnosis of consecutive slices of one batch, in order (an optional field only where
        every part holds it; ``reported`` where any part reported)."""
        joined: dict = {}
        for f in fields(cls):
            values = [getattr(p, f.name) for p in parts]
            if any(v is None for v in values):
                joined[f.name] = None
            elif isinstance(values[0], bool):
                joined[f.name] = any(values)
            else:
                joined[f.name] = np.concatenate(values)
        return cls(**joined)


@dataclass(frozen=True)
class EpisodeOutcomes:
    """Per-episode outcomes of a batch, all ``(n,)``: the three gates (bool), the final true
    pointing error (deg), the settling time (s; NaN where not settled at the end), the largest
    error over the final dwell window (deg: the settled gate at any threshold), and each episode's
    fault within its cell (int; ``None`` where unknown), which the by-fault statistics group by."""

    settled: np.ndarray
    operational: np.ndarray
    touch_once: np.ndarray
    final_error_deg: np.ndarray
    settling_time_s: np.ndarray
    dwell_max_error_deg: np.ndarray
    fault_index: np.ndarray | None = None
    window_settled: np.ndarray | None = None
    diagnosis: EpisodeDiagnosis | None = None

    @property
    def n(self) -> int:
        return len(self.settled)

    @classmethod
    def concat(cls, parts: list[EpisodeOutcomes]) -> EpisodeOutcomes:
        """The outcomes of consecutive slices of one batch, in order (``fault_index`` only where
        every part knows it)."""

        joined: dict = {}
        for f in fields(cls):
            values = [getattr(p, f.name) for p in parts]
            if any(v is None for v in values):
                joined[f.name] = None
            elif isinstance(values[0], EpisodeDiagnosis):
                joined[f.name] = EpisodeDiagnosis.concat(values)
            else:
                joined[f.name] = np.concatenate(values)
        return cls(**joined)


LIBRARIES = ("numpy", "numba", "scipy", "pydantic", "torch", "bsk", "gymnasium")

NUMERICAL_STACK = ("numpy", "scipy", "numba", "llvmlite")
"""The libraries ``constraints.txt`` pins for evaluation (torch only trains)."""


def installed_version(name: str) -> str | None:
    """The installed version of distribution ``name`` (package metadata: nothing is imported)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(name)
    except PackageNotFoundError:
        return None


def numerical_stack() -> dict[str, str]:
    """The numerical toolchain of this process: Python, the machine's architecture and the
    ``NUMERICAL_STACK`` versions. A board records it when a round is sealed, and ``leaderboard
    verify`` names what differs: the benchmark's own arithmetic does not depend on it
    (docs/numerics.md), a submission's numpy code may."""
    import platform

    stack = {"python": platform.python_version(), "machine": platform.machine()}
    return stack | {name: v for name in NUMERICAL_STACK if (v := installed_version(name)) is not None}


PACKAGED = "scftc_cli/"
"""What a packaged artifact's key is recorded under (``scftc_cli/params/pid.yaml``): the package
name, then the key its version resolves (``versions.Version.artifact_path``)."""


def collect_provenance(
    artifacts: Mapping[str, Path] | Sequence[Path] = (), controller_file: Path | None = None
) -> RunProvenance:
    """The provenance of a result produced now, from this installation.

    ``artifacts``: a built-in's packaged files by key (``ControllerSpec.artifact_files``), recorded
    as ``PACKAGED + key``; or files given on the command line, recorded by their path (relative to
    the checkout where they sit inside it). Reads installed versions from package metadata
    (nothing is imported) and asks git for the checkout's commit when the package runs from one.
    """
    import hashlib
    import platform
    import subprocess

    from scftc_cli import __version__

    root = Path(__file__).resolve().parent.parent
    commit, dirty = None, None
    if (root / ".git").exists():
        try:
            git = ["git", "-C", str(root)]
            commit = (
                subprocess.run(
                    [*git, "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5
                ).stdout.strip()
                or None
            )
            status = subprocess.run(
                [*git, "status", "--porcelain", "--untracked-files=no"],
                capture_output=True,
                text=True,
                timeout=5,
            )
            dirty = bool(status.stdout.strip()) if status.returncode == 0 else None
        except (OSError, subprocess.SubprocessError):
            commit, dirty = None, None
    sha = lambda path: hashlib.sha256(Path(path).read_bytes()).hexdigest()  # noqa: E731
    return RunProvenance(
        package_version=__version__,
        git_commit=commit,
        git_dirty=dirty,
        python=platform.python_version(),
        libraries={name: v for name in LIBRARIES if (v := installed_version(name)) is not None},
        artifacts=(
            {PACKAGED + key: sha(path) for key, path in artifacts.items()}
            if isinstance(artifacts, Mapping)
            else {
                str(Path(p).relative_to(root) if Path(p).is_relative_to(root) else p): sha(p)
                for p in artifacts
            }
        ),
        controller_file_sha256=sha(controller_file) if controller_file is not None else None,
    )


def episode_rows(controller: str, benchmark: str, draw: str, runs: list) -> list[dict]:
    """One row per episode of ``runs`` (``evaluate.CellRun``): the cell, the episode's fault and
    initial state, its gate outcomes, final error and settling time."""
    rows = []
    for run in runs:
        o, episodes = run.outcomes, run.drawn()
        for i in range(o.n):
            settling = float(o.settling_time_s[i])
            rows.append(
                {
                    "benchmark_version": benchmark,
                    "controller": controller,
                    "draw": draw,
                    "split": run.cell.split,
                    "class": run.cell.fault_class,
                    "sensor": run.cell.sensor,
                    "episode": i,
                    **episodes.describe(i),
                    **{gate: bool(getattr(o, gate)[i]) for gate in GATES},
                    "final_error_deg": float(o.final_error_deg[i]),
                    "settling_time_s": None if settling != settling else settling,
                }
            )
    return rows


def write_episode_log(path: Path, rows: list[dict]) -> Path:
    """Write ``rows`` as JSON Lines (``.jsonl``) or CSV (``.csv``, list values as JSON), atomically:
    a crash leaves the old file or none, never half of one."""
    import csv
    import io
    import json
    import os
    import tempfile

    path = Path(path)
    if path.suffix not in (".jsonl", ".csv"):
        from scftc_cli.errors import UsageError

        raise UsageError(f"--log-episodes {path}: name a .jsonl or .csv file")
    if path.suffix == ".jsonl":
        text = "".join(json.dumps(r) + "\n" for r in rows)
    else:
        buf = io.StringIO()
        columns = list(dict.fromkeys(k for r in rows for k in r))
        writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        for r in rows:
            writer.writerow({k: json.dumps(v) if isinstance(v, list) else v for k, v in r.items()})
        text = buf.getvalue()
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
