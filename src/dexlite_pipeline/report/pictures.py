"""Pictures of grasps for the report: grasps drawn at random (seeded) among each method's lift
successes and failures, drawn from two viewpoints with their four contacts marked (the hand's
forward kinematics and contact candidates), captioned with both tests' outcome; and the same
grasps in the interactive 3-D view (``report.grasp_view``).
"""

from __future__ import annotations

import base64
import html
import io
import logging
import zlib
from collections.abc import Mapping

import numpy as np

from dexlite_pipeline.evaluation.config import draw_label
from dexlite_pipeline.evaluation.labels import method_label
from dexlite_pipeline.evaluation.metrics import invalid_flags
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.report.inputs import ReportInputs
from dexlite_pipeline.report.plots import img_tag, pyplot
from dexlite_pipeline.report.tables import LADDER_METHOD_ORDER, headline_rows

log = logging.getLogger(__name__)


def pick_examples(simulated: GraspSet, method: str, count: int, seed: int = 0) -> list[tuple[int, bool]]:
    """Up to ``count`` lift successes and ``count`` lift failures of a method (rows, success flag), drawn at random.

    Drawn uniformly without replacement among the method's pictureable grasps of each
    outcome by a generator seeded with ``seed`` and the method's name (its frozen old name for a
    renamed method, ``evaluation.config.draw_label``), so a page shows
    typical grasps, not hand-picked ones, and the same inputs give the same pictures.
    Invalid grasps (no usable pose, not simulated) are not pictured.
    """
    methods = np.asarray([str(m) for m in simulated.arrays["method"]])
    success = np.asarray(simulated.arrays.get("lift_success", np.zeros(len(simulated), bool)), dtype=bool)
    picturable = ~invalid_flags(simulated.arrays)
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(draw_label(method).encode())])
    picks = []
    for outcome in (True, False):
        rows = np.nonzero((methods == method) & (success == outcome) & picturable)[0]
        chosen = rng.choice(rows, size=min(count, len(rows)), replace=False) if len(rows) else rows
        picks += [(int(r), outcome) for r in sorted(chosen)]
    return picks


def outcome_of(arrays: Mapping[str, np.ndarray], row: int) -> tuple[str, str, str]:
    """(headline, detail, css class) of one simulated grasp, from both tests.

    Held: lifted and held against all six pushes; lifted only: it rose with the hand but
    fails a push (often a palm-up carry, the object resting on the palm); dropped: it did
    not rise with the hand.
    """
    lifted = bool(np.asarray(arrays["lift_success"])[row]) if "lift_success" in arrays else False
    detail = []
    pushes = None
    if "six_dir_passed" in arrays:
        passed = np.asarray(arrays["six_dir_passed"])[row]
        pushes = int(np.sum(passed))
        detail.append(f"held against {pushes} of {len(passed)} pushes")
    elif "six_dir_success" in arrays:
        pushes = 6 if bool(np.asarray(arrays["six_dir_success"])[row]) else 0
        detail.append("held against all six pushes" if pushes == 6 else "fails the six-direction test")
    else:
        detail.append("six-direction test not run")
    reason = str(arrays["failure_reason"][row]) if "failure_reason" in arrays else ""
    if not lifted and reason:
        detail.append(reason)
    if lifted and (pushes is None or pushes == 6):
        return "HELD", " · ".join(detail), "held"
    if lifted:
        return "LIFTED, FAILS PUSHES", " · ".join(detail), "partial"
    return "DROPPED", " · ".join(detail), "dropped"


def contact_points(hand, hand_pose: np.ndarray, contact_index: np.ndarray | None, object_mesh) -> np.ndarray:
    """(4, 3) contact points of a grasp in the object frame (metres).

    The evaluation's own contacts when the store carries them (``contact_index``, the four
    candidates nearest the surface, as the energies used: entries of the hand's whole contact
    table, so a lateral grasp's side or a pinch's thumb-tip candidates too), else the four pads
    nearest the object's mesh, computed here.
    """
    import torch

    with torch.no_grad():
        frames = hand.forward(torch.as_tensor(np.asarray(hand_pose, dtype=np.float64)[None], dtype=hand.dtype, device=hand.device))
        candidates = hand.contact_candidates(frames)[0].double().cpu().numpy()
        table = frames.transform(hand.all_contact_points_local, hand.all_contact_link)[0].double().cpu().numpy()  # pads, side, thumb tip
    index = None if contact_index is None else np.asarray(contact_index, dtype=np.int64).reshape(-1)
    if index is not None and len(index) and (index >= 0).all() and (index < len(table)).all():
        return table[index]
    import trimesh

    mesh = trimesh.Trimesh(vertices=object_mesh[0], faces=object_mesh[1], process=False)
    _, distance, _ = trimesh.proximity.closest_point(mesh, candidates)
    return candidates[np.argsort(distance)[:4]]


def grasp_picture_png(hand, simulated: GraspSet, row: int, objects_dirs, size_px: int = 260) -> bytes:
    """Two viewpoints of one grasp (the renderer's hand and object) with its four contact points as red dots."""
    from dexlite_pipeline.report.render import DEFAULT_VIEWS_DEG, draw_grasp, grasp_table, hand_mesh_world, object_mesh_world

    plt = pyplot()
    pose = np.asarray(simulated.hand_pose[row], dtype=np.float64)
    hand_mesh = hand_mesh_world(hand, pose)
    object_mesh = object_mesh_world(objects_dirs, str(simulated.object_id[row]), float(simulated.scale[row]))
    index = simulated.arrays["contact_index"][row] if "contact_index" in simulated.arrays else None
    contacts = contact_points(hand, pose, index, object_mesh)
    dpi = 100
    fig = plt.figure(figsize=(size_px * len(DEFAULT_VIEWS_DEG) / dpi, size_px / dpi), dpi=dpi)
    for k, (elev, azim) in enumerate(DEFAULT_VIEWS_DEG):
        ax = fig.add_subplot(1, len(DEFAULT_VIEWS_DEG), k + 1, projection="3d")
        draw_grasp(ax, hand_mesh, object_mesh, elev, azim, grasp_table(simulated, row))
        ax.computed_zorder = False  # the dots are drawn over the meshes, so occluded contacts still show
        ax.scatter(contacts[:, 0], contacts[:, 1], contacts[:, 2], s=42, c="#e00000", edgecolors="white", linewidths=0.8, zorder=10, depthshade=False)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=1, wspace=0)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    return buffer.getvalue()


def gallery_methods(inputs: ReportInputs) -> list[str]:
    """The simulated methods in the order of the tables (headline rows, then the ladder's rungs, then the rest)."""
    present = set(str(m) for m in inputs.simulated.arrays["method"])
    table_order = list(dict.fromkeys(headline_rows(inputs.metrics)["method"])) if inputs.metrics is not None and len(inputs.metrics) else []
    table_order += [m for m in LADDER_METHOD_ORDER if m not in table_order]  # then the ladder's rows, rung by rung
    return [m for m in table_order if m in present] + sorted(present - set(table_order))


def interactive_view_html(inputs: ReportInputs) -> str:
    """The gallery's grasps in the interactive 3-D view (report.grasp_view), embedded with plotly.js (~4.7 MB)."""
    from dexlite_pipeline.report.grasp_view import grasp_view_div

    simulated = inputs.simulated
    if simulated is None or len(simulated) == 0 or inputs.rendered_per_method == 0:
        return "<p>No simulated grasps to show.</p>"
    rows = [row for method in gallery_methods(inputs) for row, _ in pick_examples(simulated, method, inputs.rendered_per_method, inputs.seed)]
    try:
        div = grasp_view_div(simulated, rows, inputs.objects_dirs)
    except (ValueError, OSError) as exc:
        log.warning("report: no interactive view: %s", exc)
        return f"<p>Not available: {html.escape(str(exc))}</p>"
    return div or "<p>No grasp to show.</p>"


def grasp_gallery(inputs: ReportInputs) -> str:
    """HTML of randomly drawn lift successes and failures for each method, outcome in large type."""
    simulated = inputs.simulated
    if simulated is None or len(simulated) == 0 or inputs.rendered_per_method == 0:
        return "<p>No simulated grasps to picture.</p>"
    from dexlite_pipeline.report.render import hand_of_store, type_of

    try:
        hand = hand_of_store(simulated.attrs)  # the hand the evaluation's stores record
    except ValueError as exc:
        log.warning("report: no pictures: %s", exc)
        return f"<p>Not available: {html.escape(str(exc))}</p>"
    parts = []
    for method in gallery_methods(inputs):
        cells = []
        for row, _ in pick_examples(simulated, method, inputs.rendered_per_method, inputs.seed):
            headline, detail, css = outcome_of(simulated.arrays, row)
            object_id, scale = str(simulated.object_id[row]), float(simulated.scale[row])
            facts = [f"{type_of(simulated.arrays, row)} grasp", object_id, f"scale {scale:.3f}"]
            for key, name in (("penetration_mm", "penetration"), ("contact_distance_mm", "contact distance")):
                if key in simulated.arrays and np.isfinite(simulated.arrays[key][row]):
                    facts.append(f"{name} {float(simulated.arrays[key][row]):.1f} mm")
            caption = (
                f"<div class='outcome {css}'>{html.escape(headline)}</div>"
                f"<div class='detail'>{html.escape(detail)}</div><div class='facts'>{html.escape(' · '.join(facts))}</div>"
            )
            alt = f"{method_label(method)}: {headline.lower()}, {object_id}"
            try:
                png = grasp_picture_png(hand, simulated, row, inputs.objects_dirs)
            except (ValueError, OSError) as exc:
                log.warning("report: cannot render %s row %d: %s", method, row, exc)
                cells.append(f"<figure><figcaption>{caption}<div class='facts'>not rendered: {html.escape(str(exc))}</div></figcaption></figure>")
                continue
            cells.append(f"<figure>{img_tag(base64.b64encode(png).decode('ascii'), alt)}<figcaption>{caption}</figcaption></figure>")
        parts.append(f"<h3>{html.escape(method_label(method))} <span class='id'>({html.escape(method)})</span></h3><div class='gallery'>{''.join(cells) or '<p>none</p>'}</div>")
    return "".join(parts)
