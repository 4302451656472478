"""Config key ``hand``: shadow (default), allegro, leap or an MJCF file; an unusable value is refused in one line
naming the key; ``hand.choice`` makes the hand object and the record a store keeps of it."""

from __future__ import annotations

import json

import pytest

from dexlite_pipeline.config import ConfigError, validate_config
from dexlite_pipeline.settings import build_config, hand_names


def test_the_default_hand_is_shadow_and_the_shipped_hands_are_known():
    from dexlite_pipeline.hand.description import HAND_NAMES

    assert build_config({}).hand == "shadow"
    assert hand_names() == HAND_NAMES  # read from data/hands/ without importing the hand code
    assert build_config({"hand": "leap"}).hand == "leap"
    validate_config({"hand": "allegro"}, partial=True)


@pytest.mark.parametrize("value, expected", [("alegro", "not a hand name and no such file"), ("missing/hand.xml", "no such file")])
def test_an_unknown_name_or_a_missing_file_is_one_line_naming_the_key(value, expected):
    with pytest.raises(ConfigError) as error:
        build_config({"hand": value})
    message = str(error.value)
    assert "\n" not in message and f"hand: {value}: {expected}" in message and "shadow, allegro, leap" in message


def test_an_mjcf_the_description_refuses_is_one_line_naming_the_key(tmp_path):
    from dexlite_pipeline.hand.choice import HandChoiceError, hand_record, resolve_hand

    broken = tmp_path / "broken.xml"
    broken.write_text('<mujoco><worldbody><body name="palm"><geom type="box" size="0.1 0.1 0.1"/></body></worldbody></mujoco>')
    assert build_config({"hand": str(broken)}).hand == str(broken)  # the file exists: the MJCF is read when the hand is made
    for make in (resolve_hand, hand_record):
        with pytest.raises(HandChoiceError) as error:
            make(str(broken))
        assert str(error.value) == f"hand: {broken}: the model has no joints"


def test_shadow_is_the_shadow_hand_and_a_file_is_recorded_with_its_sha256(tmp_path):
    import hashlib
    import sys
    from pathlib import Path

    from dexlite_pipeline.hand.choice import hand_record, resolve_hand
    from dexlite_pipeline.hand.described import DescribedHand
    from dexlite_pipeline.hand.model import JOINT_NAMES, ShadowHand

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from three_finger import write_three_finger

    shadow = resolve_hand("shadow")
    assert type(shadow) is ShadowHand and hand_record("shadow") == {"hand": "shadow", "joint_names": list(JOINT_NAMES)}
    xml = write_three_finger(tmp_path)
    hand = resolve_hand(str(xml))
    assert isinstance(hand, DescribedHand) and hand.pose_dim == 15
    record = hand_record(str(xml))
    assert record == {"hand": str(xml), "hand_sha256": hashlib.sha256(xml.read_bytes()).hexdigest(), "joint_names": list(hand.joint_names)}


@pytest.mark.parametrize("stage", ["optimize-grasps", "model-batch"])
def test_a_stage_given_a_broken_mjcf_stops_in_one_line_before_any_work(tmp_path, capsys, stage):
    from dexlite_pipeline.cli import main

    broken = tmp_path / "broken.xml"
    broken.write_text("<robot name='r'/>")
    code = main([stage, "--config-json", json.dumps({"hand": str(broken), "device": "cpu"}), "--shard", "0",
                 "--stability", str(tmp_path / "none.parquet"), "--objects", str(tmp_path), "--out", str(tmp_path / "out.zarr")])
    error = capsys.readouterr().err.strip()
    assert code == 2 and error == f"dexlite {stage}: error: hand: {broken}: not an MJCF file: its root element is <robot>, not <mujoco>"
    assert not (tmp_path / "out.zarr").exists()


def test_api_grasp_request_takes_the_hand():
    from dexlite_pipeline.api import grasp_request

    request = grasp_request(["box.obj"], "out", 4, from_scratch=True, hand="leap")
    assert request.config["hand"] == "leap" and request.model is None
