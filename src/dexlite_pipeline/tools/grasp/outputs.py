"""The files of a ``dexlite grasp`` output folder besides ``summary.md``: ``all_grasps.zarr`` (every grasp with its
failure reason and distinct-grasp label), ``grasps.zarr`` (the kept held grasps; both in the pipeline's store
schema), ``dexgraspnet/`` (DexGraspNet layout of the kept grasps and meshes, when any held), ``renders/*.png``
(different grasps) and ``view.html`` (the kept grasps in an offline, turnable 3-D view)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dexlite_pipeline.tools.grasp.request import GraspRequest
from dexlite_pipeline.tools.grasp.selection import grasp_rank, representatives

if TYPE_CHECKING:
    from dexlite_pipeline.io.grasp_store import GraspSet


def store_attrs(request: GraspRequest, mapping: dict, mesh_files: list[str], method: str, support: dict[str, str], topped_up: list[str]) -> dict:
    """What both grasp stores record about the run: how the grasps were made, the merged config ``mapping``, the
    units and size rule, every mesh file given, the pose each object stands in (``support``), the top-up and, from
    scratch, the type rounds."""
    return {
        "stage": "grasp", "method": method, "config": mapping, "units": request.units,
        "size": "resized to the training scales" if request.resize_to_training else "real size",
        "meshes": mesh_files, "support": support,
        "min_distinct": request.min_distinct if request.model else None, "topped_up": topped_up, "evaluator": request.evaluator,
        "type_rounds": None if request.model else request.type_rounds,
    }  # fmt: skip


def write_grasp_stores(out_dir: Path, tested: GraspSet, kept: GraspSet, attrs: dict, distinct_only: bool, objects_dir: Path) -> None:
    """``all_grasps.zarr`` (``tested``), ``grasps.zarr`` (``kept``, its attrs saying how they were chosen) and, when any
    grasp is kept, the DexGraspNet export of the kept grasps with their meshes from ``objects_dir``. ``attrs`` name the
    hand (``hand.choice.hand_record``), which sets the stores' pose width and the export's joint names."""
    from dexlite_pipeline.io.dexgraspnet import export_dexgraspnet
    from dexlite_pipeline.io.grasp_store import GraspSet, write_grasp_store

    write_grasp_store(out_dir / "all_grasps.zarr", tested, attrs)
    selection = "lift_success, one per distinct_label (the best)" if distinct_only else "lift_success"
    write_grasp_store(out_dir / "grasps.zarr", kept, {**attrs, "selection": selection})
    if len(kept):
        export_dexgraspnet(GraspSet(kept.arrays, {**kept.attrs, **attrs}), out_dir / "dexgraspnet", [str(objects_dir)])


def render_examples(grasps: GraspSet, labels: np.ndarray, objects_dir: Path, out_dir: Path, per_object: int, hand=None) -> list[Path]:
    """Up to ``per_object`` different held grasps per object as PNGs, the best first (one failure when none held);
    ``hand`` the grasps' hand model (None: the Shadow Hand; a described hand is drawn as its collision shapes)."""
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.report.render import grasp_table, render_grasp_png, type_of

    hand, written = ShadowHand() if hand is None else hand, []
    held = np.asarray(grasps.arrays["lift_success"], bool)
    six = np.asarray(grasps.arrays.get("six_dir_success", np.zeros(len(grasps), bool)), bool)
    best = representatives(grasps, labels)
    for object_id in sorted(set(grasps.object_id.tolist())):
        rows = [i for i in best if grasps.object_id[i] == object_id][:per_object]
        if not rows:
            finite = np.flatnonzero((grasps.object_id == object_id) & np.isfinite(grasps.hand_pose).all(axis=1))
            rows = [i for i in grasp_rank(grasps) if i in set(finite.tolist())][:1]
        for row in rows:
            if held[row]:
                outcome = "HELD: lifted, six-direction " + ("passed" if six[row] else "failed")
            else:
                outcome = f"NOT HELD: {str(grasps.arrays['failure_reason'][row] or 'dropped').replace('_', ' ')}"
            path = out_dir / f"{object_id}_{row:04d}.png"
            source = f" (from the {grasps.arrays['source'][row]})" if "source" in grasps.arrays else ""
            title = f"{object_id}  {type_of(grasps.arrays, row)} grasp {row}{source}  object radius {100 * float(grasps.scale[row]):.3g} cm\n{outcome}"
            render_grasp_png(hand, grasps.hand_pose[row], object_id, float(grasps.scale[row]), [str(objects_dir)], out=path, title=title,
                             table=grasp_table(grasps, row))
            written.append(path)
    return written


def write_view(out_dir: Path, kept: GraspSet, objects_dir: Path, title: str, hand=None) -> Path | None:
    """``view.html``: the kept grasps in one offline, turnable 3-D view; None (no file) when none is kept. ``hand``: the
    grasps' hand model (None: the one their attributes record)."""
    from dexlite_pipeline.report.grasp_view import write_grasp_set_view

    return write_grasp_set_view(out_dir / "view.html", kept, [str(objects_dir)], title=title, hand=hand) if len(kept) else None
