"""``dexlite hand-check``: the report of a usable hand (the tests' three-finger hand, a shipped one), and one-line refusals."""

from __future__ import annotations

import pytest
from three_finger import write_three_finger

from dexlite_pipeline import cli
from dexlite_pipeline.hand import check


def test_the_three_finger_hand_is_reported_and_passes(tmp_path, capsys):
    path = write_three_finger(tmp_path)
    assert cli.main(["hand-check", str(path), "--vectors", "8"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"hand three_finger: {path}\n")
    assert "links: 10, rooted at palm; fingers: 3" in out
    assert "joints: 9 hinges" in out and "f1_j1  [-0.200, +1.570]  on f11; actuator f1_a1, kp 2" in out
    assert "collision shapes: 10 (1 box, 9 capsule)" in out
    assert "contact candidates: 110 on 10 links: palm 20, f10 10, f11 10, f12 10, f20 10, f21 10, f22 10, th0 10, th1 10, th2 10" in out
    assert ", -1.000), fingers along (x)" in out  # approach -z (the first two components print as ±0.000)
    assert "FK vs MuJoCo over 8 random joint vectors" in out and out.rstrip().endswith(": ok")
    assert "\ngrasp types: power only (precision types need exactly one finger opposing the others and at least two more)\n" in out


def test_a_shipped_hand_by_name(capsys):
    assert cli.main(["hand-check", "allegro", "--vectors", "4"]) == 0
    out = capsys.readouterr().out
    assert "fingers: 4 (tips: ff_tip, mf_tip, rf_tip, th_tip); opposing the others: th_tip" in out
    assert "collision shapes: 21 (17 box, 4 capsule)" in out
    assert "grasp types: power, pinch, tripod, rim (thumb th_distal+th_tip; fingers from the index: ff_distal+ff_tip, mf_distal+mf_tip, " in out
    assert "  pinch: contacts th_distal+th_tip | th_distal+th_tip | ff_distal+ff_tip | ff_distal+ff_tip+mf_distal+mf_tip; closed 2.0 cm" in out


def test_fk_beyond_the_limits_exits_1(tmp_path, capsys, monkeypatch):
    """With a limit of 0 m no real comparison passes (float rounding remains): the verdict and the exit status follow it."""
    monkeypatch.setattr(check, "POSITION_TOL_M", 0.0)
    assert cli.main(["hand-check", str(write_three_finger(tmp_path)), "--vectors", "4"]) == 1
    assert capsys.readouterr().out.rstrip().endswith(": FAILED")


@pytest.mark.parametrize("content, reason", [
    ("hello", "not XML (syntax error: line 1, column 0)"),
    ("<mujoco><worldbody><body><geom size='0.01 0.01 0.01' type='box'/></body></worldbody></mujoco>", "the model has no joints"),
    ("<mujoco><worldbody><body><joint/><geom size='0.01'/><geom size='0.01' contype='0' conaffinity='0'/></body></worldbody>"
     "</mujoco>", "joint joint0 has no range"),
    ("<mujoco><worldbody><body><joint range='0 1'/><geom size='0.01' contype='0' conaffinity='0'/></body></worldbody></mujoco>",
     "no collision geoms (a geom with contype or conaffinity set)"),
    ("<mujoco><worldbody><body><joint range='0 1'/><geom type='capsule'/></body></worldbody></mujoco>", "MuJoCo cannot compile it"),
])  # fmt: skip
def test_an_unusable_file_is_refused_in_one_line_with_exit_2(tmp_path, capsys, content, reason):
    path = tmp_path / "hand.xml"
    path.write_text(content)
    assert cli.main(["hand-check", str(path)]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and error.startswith(f"dexlite hand-check: error: {path}: ")
    if reason:
        assert reason in error


def test_an_unknown_name_is_refused(capsys):
    assert cli.main(["hand-check", "inspire"]) == 2
    assert "no such file (a hand is shadow, allegro, leap or an MJCF file)" in capsys.readouterr().err


def test_the_picture_shows_the_contacts_on_the_palm_side(tmp_path, capsys):
    """The PNG is written, and in its palm frame the pre-grasp's contact candidates face the approach direction (+z)."""
    from dexlite_pipeline.hand.description import hand_description
    from dexlite_pipeline.report.hand_picture import posed_in_palm_frame

    path = write_three_finger(tmp_path)
    picture = tmp_path / "hand.png"
    assert cli.main(["hand-check", str(path), "--vectors", "2", "--picture", str(picture)]) == 0
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"wrote {picture}" in capsys.readouterr().out
    surface, contacts, normals, approach = posed_in_palm_frame(hand_description(path))
    assert approach.tolist() == [0.0, 0.0, 1.0] and (normals[:, 2] > 0.8).all()
    assert abs(contacts[:, 2]).max() < 0.02 and surface[:, 0].max() > 0.1  # the open hand lies flat; fingers along +x
