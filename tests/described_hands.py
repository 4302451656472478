"""The tests' three-finger hand (``tests/hand/three_finger.py``) as a ``DescribedHand``, objects for it, a grasp
constructed to hold (shared by the optimizer and lift tests of hands from an MJCF), a CLI refusal's one line, and a
small untrained model and evaluator for a hand (the stages' and tools' plumbing with a model of the hand).

The flat box lies under the palm: 6.5 x 6 x 2 cm at ``FLAT_BOX_SCALE``, centred at the object origin. The cage grasp
puts the palm (facing -z, fingers along +x) 0.5 mm above the box's top, both fingers bent 90 degrees at their first
two joints so they come down past the box's +x face (4.5 mm clear) and run under it (1.5 mm below its bottom), the
thumb straight beside the box: the box falls onto the fingers and rises with the hand. Lengths in metres.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent / "hand"))

from three_finger import write_three_finger  # noqa: E402

FLAT_BOX_ID = "flat_box"
FLAT_BOX_SCALE = 0.05  # extents (1.3, 1.2, 0.4) normalized: 6.5 x 6 x 2 cm
CYLINDER_ID = "cylinder"  # radius 0.5, height 1.2 normalized


def three_finger_hand(folder: Path):
    """The three-finger hand written to ``folder`` and described (``DescribedHand``, float32, CPU)."""
    from dexlite_pipeline.hand.described import DescribedHand

    return DescribedHand(write_three_finger(folder))


def write_objects(root: Path) -> Path:
    """The flat box and a cylinder as prepared assets under ``root`` (coarse SDF, the mesh its own convex piece)."""
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    settings = AssetBuildSettings(sdf_resolution=32, sdf_padding=0.3, surface_points=800)
    meshes = {FLAT_BOX_ID: trimesh.creation.box(extents=(1.3, 1.2, 0.4)), CYLINDER_ID: trimesh.creation.cylinder(radius=0.5, height=1.2, sections=32)}
    for object_id, mesh in meshes.items():
        write_asset(mesh, object_id, root, settings, {"source": "test"}, convex_pieces=[mesh])
    return root


def cage_grasp() -> np.ndarray:
    """(15,) the grasp of the flat box that holds it (module docstring): palm pose, then the nine joints in qpos order
    (f1_j0..2, f2_j0..2, th_j0..2)."""
    pose = np.zeros(15)
    pose[2] = 0.01 + 0.01 + 0.0005  # box top + palm half thickness + 0.5 mm
    pose[6:9] = (1.57, 1.57, 0.0)
    pose[9:12] = (1.57, 1.57, 0.0)
    return pose


def far_grasp() -> np.ndarray:
    """The cage grasp 30 cm above the box: it touches nothing and holds nothing."""
    pose = cage_grasp()
    pose[2] += 0.3
    return pose


def one_line_cli_error(capsys, arguments: list[str]) -> str:
    """``dexlite ARGUMENTS`` exits with status 2 and one line on stderr (a refusal); that line."""
    from dexlite_pipeline.cli import main

    capsys.readouterr()
    assert main(arguments) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1, error
    return error


def untrained_model_and_evaluator(folder: Path, hand: str) -> tuple[Path, Path]:
    """A small CVAE and grasp evaluator with untrained weights for ``hand`` (config key ``hand``), saved in ``folder``: model
    files for testing the plumbing, not the grasps."""
    import dataclasses

    from dexlite_pipeline.hand.choice import hand_record
    from dexlite_pipeline.model.checkpoint import save_checkpoint
    from dexlite_pipeline.model.config import ModelConfig
    from dexlite_pipeline.model.evaluator import EvaluatorConfig, GraspEvaluator, save_evaluator
    from dexlite_pipeline.model.network import GraspCVAE

    @dataclasses.dataclass
    class Trained:
        points_per_cloud: int = 64

    small = ModelConfig(pointnet_widths=(16, 32), encoder_hidden=(32,), decoder_hidden=(32,), latent_dim=8, normalization="none")
    save_checkpoint(folder / "cvae.pt", GraspCVAE(small, hand_record=hand_record(hand)), Trained(), {"seed": 0})
    config = EvaluatorConfig(points_per_cloud=64, pointnet_points=32, pointnet_widths=(8, 16), hand_points_per_shape=1, hidden_sizes=(16,))
    save_evaluator(folder / "evaluator.pt", GraspEvaluator(config, "cpu", hand), config, {"train_object_ids": []})
    return folder / "cvae.pt", folder / "evaluator.pt"
