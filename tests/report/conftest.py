"""Fixture: one prepared object (a box) with a catalog marking it held out."""

import pytest
from report_synthetic import write_heldout_box


@pytest.fixture(scope="session")
def tiny_objects(tmp_path_factory):
    """One prepared object (a box, normalized size) with a catalog marking it held out."""
    return write_heldout_box(tmp_path_factory.mktemp("objects"))
