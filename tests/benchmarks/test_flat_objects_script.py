"""benchmarks/experiments/flat_objects.py: the height profile against the fingertips and the per-family grasp table."""

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet, write_grasp_store


def test_fingertip_radii_are_the_distal_capsules(benchmark_script):
    radii = benchmark_script("flat_objects").fingertip_radii()
    assert abs(radii["ffdistal"] - 0.00705) < 1e-6 and abs(radii["thdistal"] - 0.00918) < 1e-6


def test_height_profile_of_a_flat_and_a_tall_box(benchmark_script):
    """A 5 mm slab's sides lie wholly below both fingertips' radii; a 3 cm box's sides mostly above them."""
    import trimesh

    script = benchmark_script("flat_objects")
    radii = {"ffdistal": 0.00705, "thdistal": 0.00918}
    slab = trimesh.creation.box(extents=(0.1, 0.02, 0.005))
    slab.apply_translation((0, 0, 0.0025))
    low = script.height_profile(slab, radii, samples=4000)
    assert abs(low["height_m"] - 0.005) < 1e-9 and abs(low["side_share"] - 0.0012 / 0.0052) < 0.02
    assert low["side_above"] == {"ffdistal": 0.0, "thdistal": 0.0} and low["side_height_m"][2] <= 0.005 + 1e-9
    box = trimesh.creation.box(extents=(0.05, 0.05, 0.03))
    box.apply_translation((0, 0, 0.015))
    tall = script.height_profile(box, radii, samples=4000)
    assert 0.7 < tall["side_above"]["ffdistal"] < 0.8 and 0.65 < tall["side_above"]["thdistal"] < tall["side_above"]["ffdistal"]


def test_grasp_table_counts_threshold_reasons_and_contact_heights(tmp_path, benchmark_script):
    """Two pinches of a spoon on a table 1 m below the hand's origin: the table gives the first threshold each fails, the
    lift failures and the contact heights (the contact points of the zero pose, measured from the table)."""
    import torch

    from dexlite_pipeline.hand.model import ShadowHand

    script = benchmark_script("flat_objects")
    grasps = GraspSet({
        "hand_pose": np.zeros((2, 28), np.float32), "object_id": np.asarray(["user-household-spoon-900"] * 2, dtype=object),
        "scale": np.ones(2, np.float32), "grasp_type": np.asarray(["pinch"] * 2, dtype=object),
        "E_fc": np.asarray([0.1, 2.0], np.float32), "E_dis": np.asarray([0.001, 0.001], np.float32), "E_pen": np.zeros(2, np.float32),
        "penetration_mm": np.asarray([1.0, 1.0], np.float32), "stopped_at_iteration": np.asarray([0, 600], np.int32),
        "lift_success": np.zeros(2, bool), "lift_ratio": np.asarray([0.0, np.nan], np.float32),
        "failure_reason": np.asarray(["dropped", "not_tested: optimization stopped early (hopeless)"], dtype=object),
        "contact_index": np.asarray([[130, 131, 20, 21]] * 2, np.int16),
        "support_normal": np.asarray([[0.0, 0.0, 1.0]] * 2, np.float32), "support_offset_m": np.ones(2, np.float32),
    })  # fmt: skip
    write_grasp_store(tmp_path / "pinch" / "all_grasps.zarr", grasps, {})
    lines = script.grasp_table([tmp_path])
    assert len(lines) == 3 and lines[2].startswith("| spoon | pinch | 2 | 1 | ")
    cells = [c.strip() for c in lines[2].split("|")]
    assert cells[9] == "within 1, e_fc 1" and cells[10] == "0" and cells[11] == "dropped 1, not_tested 1"
    hand = ShadowHand()
    points = hand.forward(torch.zeros(1, 28)).transform(hand.all_contact_points_local, hand.all_contact_link)[0, [130, 131, 20, 21]]
    assert abs(float(cells[13].split(" / ")[1]) - 1000 * (1.0 + float(points[:, 2].min()))) < 0.01
