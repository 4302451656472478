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
