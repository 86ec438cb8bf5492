"""scftc-v4 published: its battery is frozen, so every command flies its held-out split; the
admission rule reports there and decides on train, and a version without a rule says so."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.versions import get_version, published_names

runner = CliRunner()


def test_v4_is_published():
    assert not get_version("scftc-v4").draft
    assert "scftc-v4" in published_names()


def test_a_deployable_controller_flies_the_held_out_split():
    result = runner.invoke(
        app,
        ["eval", "--benchmark", "scftc-v4", "--controller", "pid", "--split", "test"]
        + ["--class", "incipient", "--n-faults", "2", "--n-seeds", "1", "--format", "json"],
    )
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["benchmark_version"] == "scftc-v4" and doc["cells"][0]["split"] == "test"


def test_admission_needs_a_rule():
    result = runner.invoke(app, ["admission", "--benchmark", "scftc-v3"])
    assert result.exit_code == 2 and "has no admission rule" in result.output


def test_admission_on_a_small_draw_prints_the_table_on_either_split():
    for split in ("train", "test"):
        result = runner.invoke(
            app,
            ["admission", "--benchmark", "scftc-v4", "--split", split, "--n-faults", "2", "--n-seeds", "1"],
        )
        assert result.exit_code in (0, 1), result.output
        header = f"| class ({split}) | oracle settled % (>= 95) | pid settled % (<= 50) | rule | ranked |"
        assert header in result.output
        assert result.output.count("\n| ") >= len(get_version("scftc-v4").spec.fault_classes)


def test_the_gym_environment_flies_v4_episodes_of_either_split():
    import gymnasium

    import scftc_cli  # noqa: F401  (registers the environments)

    for split in ("train", "test"):
        env = gymnasium.make("scftc/AttitudeFTC-v4", split=split)
        obs, info = env.reset(seed=0)
        assert obs.shape == (26,) and "fault" not in info
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert obs.shape == (26,) and not terminated and 0.0 <= info["pointing_error_deg"] <= 180.0
