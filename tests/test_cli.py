"""The dispatcher: OpenMP's wait policy is set before a stage (and torch) loads, unless the user set it."""

import os

import pytest

from dexlite_pipeline import cli


def test_openmp_threads_wait_passively_unless_the_user_says_otherwise(monkeypatch):
    monkeypatch.delenv("OMP_WAIT_POLICY", raising=False)
    with pytest.raises(SystemExit):
        cli.main(["energy", "--help"])
    assert os.environ["OMP_WAIT_POLICY"] == "PASSIVE"
    monkeypatch.setenv("OMP_WAIT_POLICY", "ACTIVE")
    with pytest.raises(SystemExit):
        cli.main(["energy", "--help"])
    assert os.environ["OMP_WAIT_POLICY"] == "ACTIVE"


def test_an_unreadable_input_file_is_one_line_not_a_traceback(tmp_path, capsys):
    """Any OSError (here a folder given as a CSV) is bad input to report, like a ValueError."""
    assert cli.main(["curate", "--step", "aggregate", "--summary", str(tmp_path), "--out", str(tmp_path / "merged.csv")]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and error.startswith("dexlite curate: error:") and str(tmp_path) in error


def test_help_groups_user_commands_before_pipeline_stages_in_plain_text(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    text = capsys.readouterr().out
    users, stages = text.index("commands for your meshes and grasp stores:"), text.index("pipeline stages")
    for name in cli.USER_COMMANDS:
        assert users < text.index(f"\n  {name} ") < stages
    for name in cli.PIPELINE_STAGES:
        assert text.index(f"\n  {name} ") > stages
    assert "``" not in text and ":func:" not in text  # no reST markup
    assert set(cli.COMMANDS) == set(cli.USER_COMMANDS) | set(cli.PIPELINE_STAGES)
    assert {"grasp", "lift-test", "energy", "render", "import-dexgraspnet", "export-dexgraspnet", "dataset-add", "hand-check"} == set(cli.USER_COMMANDS)


@pytest.mark.parametrize("command", sorted(cli.COMMANDS))
def test_every_command_help_is_plain_text(command, capsys):
    with pytest.raises(SystemExit):
        cli.main([command, "--help"])
    assert "``" not in capsys.readouterr().out


@pytest.mark.parametrize("command", ["lift-test", "energy", "render", "export-dexgraspnet"])
def test_user_commands_share_flag_names(command):
    parser = cli.argparse.ArgumentParser()
    cli.importlib.import_module(f"dexlite_pipeline.{cli.COMMANDS[command][0]}").add_arguments(parser)
    options = set(parser._option_string_actions)
    assert "--out" in options and "--objects" in options and "--config" not in options
    if command in ("lift-test", "energy"):
        assert "--config-json" in options


@pytest.mark.parametrize("command", ["lift-test", "energy", "render"])
def test_objects_default_to_the_folder_beside_the_store_or_one_line_error(command, tmp_path, capsys):
    store = tmp_path / "run" / "grasps.zarr"
    store.parent.mkdir()
    code = cli.main([command, str(store), "--out", str(tmp_path / "out")])
    error = capsys.readouterr().err.strip()
    assert code == 2 and len(error.splitlines()) == 1
    assert error == f"dexlite {command}: error: {store}: no --objects given and no prepared objects at {store.parent / 'objects'} (give --objects DIR)"
