"""scftc-v4 while it is a draft: its held-out split is closed to deployable controllers (and open to
the privileged oracle), a version without an admission rule says so, and the commands fly v4's
train split like any other version's."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.versions import get_version, published_names

runner = CliRunner()


def test_v4_is_a_draft_with_no_board():
    assert get_version("scftc-v4").draft
    assert "scftc-v4" not in published_names()


def test_a_deployable_controller_may_not_fly_the_held_out_split_of_a_draft():
    for controller, split in (("pid", "test"), ("pd", "test")):
        result = runner.invoke(
            app,
            ["eval", "--benchmark", "scftc-v4", "--controller", controller, "--split", split]
            + ["--class", "sign", "--n-faults", "1", "--n-seeds", "1"],
        )
        assert result.exit_code == 2, result.output
        assert "is a draft" in result.output and "its train split is open" in result.output


def test_the_oracle_and_the_train_split_fly():
    for controller, split in (("oracle", "test"), ("pid", "train")):
        result = runner.invoke(
            app,
            ["eval", "--benchmark", "scftc-v4", "--controller", controller, "--split", split]
            + ["--class", "incipient", "--n-faults", "2", "--n-seeds", "1", "--format", "json"],
        )
        assert result.exit_code == 0, result.output
        doc = json.loads(result.stdout)
        assert doc["benchmark_version"] == "scftc-v4" and doc["cells"][0]["split"] == split


def test_admission_needs_a_rule():
    result = runner.invoke(app, ["admission", "--benchmark", "scftc-v3"])
    assert result.exit_code == 2 and "has no admission rule" in result.output


def test_admission_on_a_small_train_draw_prints_the_table():
    result = runner.invoke(app, ["admission", "--benchmark", "scftc-v4", "--n-faults", "2", "--n-seeds", "1"])
    assert result.exit_code in (0, 1), result.output
    header = "| class (train) | oracle settled % (>= 95) | pid settled % (<= 50) | rule | ranked |"
    assert header in result.output
    assert result.output.count("\n| ") >= len(get_version("scftc-v4").spec.fault_classes)


def test_reproduce_refuses_a_draft_before_flying(tmp_path):
    result = runner.invoke(app, ["reproduce", "--benchmark", "scftc-v4", "--out", str(tmp_path / "out")])
    assert result.exit_code == 2 and "is a draft" in result.output and "scftc admission" in result.output
    assert not (tmp_path / "out").exists()


def test_the_gym_environment_flies_v4_train_episodes_and_refuses_its_held_out_split():
    import gymnasium
    import pytest

    import scftc_cli  # noqa: F401  (registers the environments)
    from scftc_cli.errors import UsageError

    env = gymnasium.make("scftc/AttitudeFTC-v4")
    obs, info = env.reset(seed=0)
    assert obs.shape == (26,) and "fault" not in info
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert obs.shape == (26,) and not terminated and 0.0 <= info["pointing_error_deg"] <= 180.0
    with pytest.raises(UsageError, match="is a draft"):
        gymnasium.make("scftc/AttitudeFTC-v4", split="test")
