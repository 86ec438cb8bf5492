"""Who holds the round key, and what code the jobs that can write run (issue: the round key was in
the environment of everything the seal job ran, apt-get, pip installs, any build step and
verify-boards, and actions were named by tag).

The key reaches one step of all the workflows, the seal's ``make land-and-seal`` (a target with no
prerequisites), after everything is installed; every action is pinned by commit."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
WORKFLOWS = sorted((ROOT / ".github" / "workflows").glob("*.yml"))


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
