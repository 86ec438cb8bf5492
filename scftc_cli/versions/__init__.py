"""Benchmark versions: one folder each, registered by one line, found by name.

A version is a folder ``scftc_cli/versions/<name>/`` laid out like the package (``spec.py``,
``sim/``, ``controllers/``, ``training/``, ``study.py``, ``envs.py``, ``params/``, ``weights/``)
whose ``__init__.py`` holds one ``Version`` record: its spec and, as ``"module:attr"`` strings
loaded on first use, everything else the layers above ask of it. ``VERSIONS`` below names the
records, one line per version; the first is the default of every command. Nothing outside this
folder names a version: it asks here (``get_version``, ``get_spec``, ``version_names``).

Importing this module imports no version: the names and the default come from ``VERSIONS`` alone,
so ``scftc --help`` can list them for free.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from scftc_cli.errors import LeaderboardError, UnknownNameError
from scftc_cli.loading import load

if TYPE_CHECKING:
    from scftc_cli.protocol import Controller
    from scftc_cli.spec import BenchmarkSpec

VERSIONS: dict[str, str] = {
    "scftc-v1": "scftc_cli.versions.v1:VERSION",
    "scftc-v2": "scftc_cli.versions.v2:VERSION",
    "scftc-v3": "scftc_cli.versions.v3:VERSION",
    "scftc-v4": "scftc_cli.versions.v4:VERSION",
}
"""Every registered version: its name and its ``Version`` record, in the order commands list them;
the first is every command's default. ``register`` adds one at run time (tests)."""

TUNER = "scftc_cli.training.tuning:tune_controller"
"""The trainer of every controller tuned by the generic tuner (a version's ``tuning`` specs)."""


@dataclass(frozen=True)
class ControllerSpec:
    """One built-in controller of a version.

    Attributes:
        name: the name on the command line and the board (unique within its version).
        entry_point: ``"module:Class"``; the class is built with no arguments.
        summary: one line for ``scftc list`` and the board.
        privileged: an oracle that is handed the true fault (an upper bound, never ranked).
        artifacts: the keys of the files it loads (tuned parameters, weights), hashed into every
            result's provenance; its version resolves each key to a file (``Version.artifact_path``).
        family: ``reference`` (fault-unaware baselines), ``classical`` (adaptive and estimation
            laws), ``learned`` (trained networks) or ``oracle`` (privileged upper bounds): how
            tables and figures group the battery.
        benchmark: the version it flies (set when its version is registered).
    """

    name: str
    entry_point: str
    summary: str
    privileged: bool = False
    artifacts: tuple[str, ...] = ()
    family: str = "classical"
    benchmark: str = ""

    def load(self) -> type[Controller]:
        """Import the controller's class."""
        return load(self.entry_point)

    def make(self) -> Controller:
        """A fresh instance."""
        return self.load()()

    def artifact_files(self) -> dict[str, Path]:
        """Each artifact's key and the file it names."""
        if not self.artifacts:
            return {}
        version = get_version(self.benchmark)
        return {key: version.artifact_path(key) for key in self.artifacts}

    def artifact_paths(self) -> list[Path]:
        """The files of ``artifacts``, in order."""
        return list(self.artifact_files().values())


@dataclass(frozen=True)
class GymEnv:
    """A gymnasium environment of a version: its id and ``"module:Class"`` entry points."""

    id: str
    entry_point: str
    vector_entry_point: str


@dataclass(frozen=True)
class StudyPlan:
    """What ``scftc reproduce`` measures on a version, beyond the battery on its held-out classes.

    Attributes:
        sensors_in_battery: every controller flies the sensor classes (noisy redundant sensors are
            part of what a controller is judged on); otherwise a deployed controller and
            ``sensor_oracle`` fly them, as the source study's sensor table did.
        regime_rule: the sentence that says which sensor faults can be fought from the observation.
        deployed_preference: the deployed controller of the sensor table, when registered.
        sensor_oracle: the oracle beside it.
        detector: a controller whose fault detector the study measures (delay, false alarms), or
            ``None``; it must record ``alarm_steps`` and ``change_steps`` (``study/detection.py``).
        crosscheck: ``"module:attr"`` of its Basilisk cross-check plan (``study/crosscheck.py``),
            or ``None``.
    """

    sensors_in_battery: bool
    regime_rule: str
    deployed_preference: str | None = None
    sensor_oracle: str = "teacher"
    detector: str | None = None
    crosscheck: str | None = None


@dataclass(frozen=True)
class Version:
    """Everything the layers above a version ask of it.

    Attributes:
        spec: the version as data (``spec.BenchmarkSpec``).
        testbed: ``"module:attr"`` of its simulator (``sim.testbed.Testbed``).
        controllers: its built-in controllers in battery order (deployable, then oracles).
        folder: its folder, which holds ``params/`` and ``weights/``.
        artifact_prefix: what its artifacts' keys carry between the kind and the file name: a key
            is ``<kind>/<prefix><file>`` (``params/v2/pid.yaml``: the path the file had when the
            version's board was sealed), and the file is ``<folder>/<kind>/<file>``.
        trainers: controller -> ``"module:function"`` of its trainer (``TUNER`` for the tuned ones).
        tuning: ``"module:attr"`` of its ``training.tuning.Tuning`` (specs and budgets), if any.
        study: what ``scftc reproduce`` measures on it.
        envs: its gymnasium environments.
        definition: its written definition (a path from the repository root) and the heading of
            that document's table of every spec value.
        alias: the short name its spec keeps in ``scftc_cli.spec`` (``spec.V1``).
        draft: still being calibrated: it has no board, and the loops over published versions
            (``published_names``: boards, ``make reproduce``, verification) leave it out.
        in_training: ports with a trainer whose committed artifact does not exist yet: ``scftc
            train`` produces it, nothing else sees them; each moves to ``controllers`` once its
            artifact is committed.
        superseded_by: the version that replaces it, if any: its board stays published and
            verifiable, but opens no round and lands no submission (``check_accepts_entries``).
    """

    spec: BenchmarkSpec[Any, Any, Any]
    testbed: str
    controllers: tuple[ControllerSpec, ...]
    folder: Path
    study: StudyPlan
    artifact_prefix: str = ""
    trainers: Mapping[str, str] = field(default_factory=dict)
    tuning: str | None = None
    envs: tuple[GymEnv, ...] = ()
    definition: tuple[str, str] = ("", "")
    alias: str = ""
    draft: bool = False
    in_training: tuple[ControllerSpec, ...] = ()
    superseded_by: str | None = None

    def __post_init__(self) -> None:
        for name in ("controllers", "in_training"):
            bound = tuple(replace(c, benchmark=self.name) for c in getattr(self, name))
            object.__setattr__(self, name, bound)

    @property
    def name(self) -> str:
        return self.spec.version

    @property
    def params_dir(self) -> Path:
        """Where its tuned parameters live: ``<folder>/params``."""
        return self.folder / "params"

    @property
    def weights_dir(self) -> Path:
        """Where its trained weights live: ``<folder>/weights``."""
        return self.folder / "weights"

    def artifact_path(self, key: str) -> Path:
        """The file of artifact ``key`` (``Version.artifact_prefix``)."""
        kind, _, rest = key.partition("/")
        if not rest.startswith(self.artifact_prefix):
            raise ValueError(f"{key} is not an artifact key of {self.name}")
        return self.folder / kind / rest.removeprefix(self.artifact_prefix)

    def artifact_key(self, path: Path) -> str:
        """The key of the artifact file ``path`` inside the folder (``artifact_path``'s inverse)."""
        kind, *rest = Path(path).resolve().relative_to(self.folder).parts
        return f"{kind}/{self.artifact_prefix}{'/'.join(rest)}"


_loaded: dict[str, Version] = {}


def register(name: str, target: str | Version) -> None:
    """Register version ``name``: its ``Version`` record, or the ``"module:attr"`` that holds it.
    (The built-in versions are the lines of ``VERSIONS``; this is for versions defined elsewhere.)"""
    VERSIONS[name] = target if isinstance(target, str) else f"<registered {name}>"
    _loaded.pop(name, None)
    if isinstance(target, Version):
        _check(name, target)
        _loaded[name] = target


def unregister(name: str) -> None:
    """Forget version ``name`` (tests that registered one)."""
    VERSIONS.pop(name, None)
    _loaded.pop(name, None)


def _check(name: str, version: Version) -> None:
    if version.name != name:
        raise ValueError(f"version {name} is registered with the spec of {version.name}")


def version_names() -> tuple[str, ...]:
    """Every registered version's name, the default first."""
    return tuple(VERSIONS)


def published_names() -> tuple[str, ...]:
    """The registered versions that are not drafts (``Version.draft``), in order: those with a
    board, which the board commands and the Makefile's loops go over."""
    return tuple(name for name in VERSIONS if not get_version(name).draft)


def default_version() -> str:
    """The version every command flies unless told otherwise: the first registered."""
    return next(iter(VERSIONS))


def benchmark_option(name: str) -> str:
    """``--benchmark NAME `` for any version but the default, else nothing: how messages write a
    command for version ``name``."""
    return "" if name == default_version() else f"--benchmark {name} "


def version_folder(name: str) -> Path:
    """The folder of version ``name`` (``scftc_cli/versions/<name>/``), found without importing it."""
    import importlib.util

    if name not in VERSIONS:
        raise UnknownNameError("benchmark version", name, VERSIONS)
    spec = importlib.util.find_spec(VERSIONS[name].split(":")[0])
    assert spec is not None and spec.origin is not None  # a registered version is a package
    return Path(spec.origin).parent


def get_version(name: str) -> Version:
    """The ``Version`` of ``name`` (imported on first use); an unknown name suggests the closest."""
    if name not in VERSIONS:
        raise UnknownNameError("benchmark version", name, VERSIONS)
    if name not in _loaded:
        version = load(VERSIONS[name])
        _check(name, version)
        _loaded[name] = version
    return _loaded[name]


def get_spec(name: str | None = None) -> BenchmarkSpec[Any, Any, Any]:
    """The spec of version ``name`` (the default version's when ``None``)."""
    return get_version(default_version() if name is None else name).spec


def all_versions() -> list[Version]:
    """Every registered version, in order (each imported)."""
    return [get_version(name) for name in VERSIONS]


def spec_by_alias(alias: str) -> BenchmarkSpec[Any, Any, Any] | None:
    """The spec of the registered version whose ``alias`` is ``alias`` (``None``: none has it)."""
    for version in all_versions():
        if version.alias and version.alias == alias:
            return version.spec
    return None


def check_accepts_entries(name: str) -> None:
    """Refuse a new round or a landing submission on a superseded version's board (its entries and
    rounds stay as they are, verifiable)."""
    successor = get_version(name).superseded_by
    if successor is not None:
        raise LeaderboardError(
            f"{name} is superseded by {successor}: its board takes no new round or submission; "
            f"submit to {successor} instead (SUBMISSION['benchmark'] = '{successor}')"
        )
