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
