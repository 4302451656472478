"""The hand models shipped in ``data/hands/``: complete, licensed, compiled by MuJoCo, and packaged in the wheel.

The wheel's package data is checked against pyproject's globs (setuptools matches them with ``glob`` relative
to the package), so a new file in a hand's folder that the wheel would leave out fails here, in a second,
instead of at run time on a user's machine.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "dexlite_pipeline"
HANDS = PACKAGE / "data" / "hands"
SHIPPED = ("allegro", "leap")


def _packaged_files() -> set[Path]:
    patterns = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["dexlite_pipeline"]
    return {path for pattern in patterns for path in PACKAGE.glob(pattern) if path.is_file()}


def test_every_file_of_the_shipped_hands_is_package_data():
    files = {p for p in HANDS.rglob("*") if p.is_file() and "__pycache__" not in p.parts}
    assert {p.parent.name for p in files if p.name == "right_hand.xml"} == set(SHIPPED)
    missing = sorted(str(p.relative_to(PACKAGE)) for p in files - _packaged_files())
    assert not missing, f"not in pyproject's package-data: {missing}"


@pytest.mark.parametrize("name", SHIPPED)
def test_a_shipped_hand_has_its_licence_its_attribution_and_every_mesh_it_names(name):
    import xml.etree.ElementTree as ET

    folder = HANDS / name
    assert (folder / "LICENSE").read_text().strip().startswith("Copyright")
    readme = (folder / "README.md").read_text()
    assert "mujoco_menagerie" in readme and "Licence" in readme
    root = ET.parse(folder / "right_hand.xml").getroot()
    meshdir = folder / root.find("compiler").get("meshdir", ".")
    named = {m.get("file") for m in root.iter("mesh")}
    on_disk = {p.name for p in (folder / "assets").iterdir()}
    assert named == on_disk, f"meshes named but absent: {named - on_disk}; present but unused: {on_disk - named}"
    assert all((meshdir / f).is_file() for f in named)


@pytest.mark.parametrize("name, joints", [("allegro", 16), ("leap", 16)])
def test_mujoco_compiles_a_shipped_hand_from_its_folder(name, joints):
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(HANDS / name / "right_hand.xml"))
    assert model.njnt == joints and model.nu == joints
