"""An interactive 3-D view of grasps: one self-contained HTML file that works offline.

The object mesh and the grasps' hand at each grasp pose (the Shadow Hand's visual meshes, or a
hand from its MJCF as its collision shapes, placed by the hand's ``forward``, as in ``report.render``), drawn with plotly's ``Mesh3d``; plotly.js
is embedded in the file, so nothing is fetched from the network. A slider shows one grasp at
a time, titled with its results (held or not, six-direction pushes, energies). The view turns
and zooms with the mouse. Meshes are decimated (``HAND_FACES``, ``OBJECT_FACES``) and arrays
are stored as float32/uint16 binary, so a grasp costs about 50 kB on top of plotly.js (~4.7 MB).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dexlite_pipeline.report.render import HAND_RGB, OBJECT_RGB, HandVisual, hand_mesh_world, hand_of_store, hand_visual, object_mesh_world, type_of, visual_of

HAND_FACES = 3000  # faces of the whole decimated hand (the full visual mesh has about 20,000)
OBJECT_FACES = 4000  # an object mesh with more faces is decimated to this many
DEFAULT_MAX_GRASPS = 24  # grasps per view; more are chosen evenly across objects
SIX_DIRECTIONS = ("+x", "−x", "+y", "−y", "+z", "−z")  # column order of six_dir_passed
# Energy terms shown in a grasp's title when the store has them: array -> (label, unit, format).
ENERGY_LABELS = {
    "E_fc": ("E_fc", "", "{:.3g}"),
    "E_dis": ("E_dis", " m", "{:.3g}"),
    "E_pen": ("E_pen", " m", "{:.3g}"),
    "E_spen": ("E_spen", " m", "{:.3g}"),
    "E_joints": ("E_joints", " rad", "{:.3g}"),
    "penetration_mm": ("penetration", " mm", "{:.1f}"),
}


class GraspViewError(ValueError):
    """Grasps that cannot be shown (no grasp, an object mesh missing, a bad pose)."""


@dataclass(frozen=True)
class ViewGrasp:
    """One grasp to show: the key of its object mesh, its 28-vector pose (object frame, metres) and its title."""

    object_key: str
    hand_pose: np.ndarray
    label: str


def _rgb(rgb: tuple[float, float, float]) -> str:
    return "rgb({},{},{})".format(*(round(255 * c) for c in rgb))


HAND_COLOR = _rgb(HAND_RGB)  # the colours of the static pictures
OBJECT_COLOR = _rgb(OBJECT_RGB)


def decimate(vertices: np.ndarray, faces: np.ndarray, max_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """The mesh with at most about ``max_faces`` faces (quadric decimation); small meshes unchanged."""
    if len(faces) <= max_faces:
        return np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    import fast_simplification

    points, triangles = fast_simplification.simplify(np.asarray(vertices, np.float32), np.asarray(faces, np.int32), target_reduction=1.0 - max_faces / len(faces))
    return np.asarray(points, np.float64), np.asarray(triangles, np.int64)


@functools.cache
def decimated_hand_visual(max_faces: int = HAND_FACES) -> HandVisual:
    """The Shadow Hand's visual mesh with about ``max_faces`` faces, each link's geoms decimated in the link's frame."""
    return decimated_visual(hand_visual(), max_faces)


def view_visual(hand) -> HandVisual:
    """What the 3-D view draws of ``hand``: the Shadow Hand's decimated visual mesh, or a described hand's collision
    shapes (``report.render.visual_of``) decimated to about ``HAND_FACES`` faces when they have more."""
    if getattr(hand, "description", None) is None:
        return decimated_hand_visual()
    full = visual_of(hand)
    return full if len(full.faces) <= HAND_FACES else decimated_visual(full, HAND_FACES)


def decimated_visual(full: HandVisual, max_faces: int) -> HandVisual:
    """``full`` with about ``max_faces`` faces, each link's geoms decimated in the link's frame."""
    keep = max_faces / len(full.faces)
    face_link = full.vertex_link[full.faces[:, 0]]
    vertices, faces, links = [], [], []
    offset = 0
    for link in np.unique(face_link):
        link_faces = full.faces[face_link == link]
        used = np.unique(link_faces)
        local = np.searchsorted(used, link_faces)
        v, f = decimate(full.vertices[used], local, max(12, int(round(keep * len(link_faces)))))
        vertices.append(v)
        faces.append(f + offset)
        links.append(np.full(len(v), link))
        offset += len(v)
    return HandVisual(np.concatenate(vertices), np.concatenate(faces), np.concatenate(links))


def _mesh_trace(vertices: np.ndarray, faces: np.ndarray, color: str, name: str, visible: bool):
    import plotly.graph_objects as go

    v = np.asarray(vertices, np.float32)
    f = np.asarray(faces, np.uint16 if len(v) < 2**16 else np.uint32)
    return go.Mesh3d(
        x=v[:, 0], y=v[:, 1], z=v[:, 2], i=f[:, 0], j=f[:, 1], k=f[:, 2],
        color=color, flatshading=True, name=name, visible=visible, hoverinfo="name",
        lighting={"ambient": 0.6, "diffuse": 0.7, "specular": 0.05, "roughness": 0.9}, lightposition={"x": 1e5, "y": -1e5, "z": 1e5},
    )


def grasp_view_figure(objects: Mapping[str, tuple[np.ndarray, np.ndarray]], grasps: Sequence[ViewGrasp], title: str = "", hand=None):
    """A plotly figure: each object mesh once, the hand at each grasp, a slider showing one grasp at a time.

    ``objects`` maps an object key to its mesh (vertices in metres in the grasps' object frame,
    faces); every grasp's ``object_key`` must be one of its keys. ``hand``: the hand model the poses are of (None: the
    Shadow Hand).
    """
    import plotly.graph_objects as go

    from dexlite_pipeline.hand import ShadowHand

    if not grasps:
        raise GraspViewError("no grasp to show")
    missing = sorted({g.object_key for g in grasps} - set(objects))
    if missing:
        raise GraspViewError(f"no mesh for object(s) {', '.join(missing)}")
    keys = list(dict.fromkeys(g.object_key for g in grasps))
    hand = ShadowHand() if hand is None else hand
    visual = view_visual(hand)
    fig = go.Figure()
    for key in keys:
        v, f = decimate(*objects[key], OBJECT_FACES)
        fig.add_trace(_mesh_trace(v, f, OBJECT_COLOR, f"object {key}", key == grasps[0].object_key))
    for n, grasp in enumerate(grasps):
        try:
            v, f = hand_mesh_world(hand, grasp.hand_pose, visual)
        except ValueError as exc:
            raise GraspViewError(f"grasp {n + 1} ({grasp.object_key}): {exc}") from exc
        fig.add_trace(_mesh_trace(v, f, HAND_COLOR, f"hand, grasp {n + 1}", n == 0))
    steps = []
    for n, grasp in enumerate(grasps):
        visible = [key == grasp.object_key for key in keys] + [m == n for m in range(len(grasps))]
        steps.append({"method": "update", "label": str(n + 1), "args": [{"visible": visible}, {"title.text": _title(title, grasp.label)}]})
    axis = {"visible": False, "showbackground": False}
    fig.update_layout(
        title={"text": _title(title, grasps[0].label), "font": {"size": 13}, "x": 0.01, "xanchor": "left"},
        scene={"xaxis": axis, "yaxis": axis, "zaxis": axis, "aspectmode": "data", "camera": {"eye": {"x": 1.4, "y": -1.4, "z": 0.9}}},
        sliders=[{"active": 0, "steps": steps, "currentvalue": {"prefix": "grasp "}, "pad": {"t": 10}}],
        margin={"l": 0, "r": 0, "t": 80, "b": 0}, showlegend=False, paper_bgcolor="white",
        annotations=[{"text": "object: blue · hand: orange · drag to turn, scroll to zoom", "showarrow": False, "xref": "paper", "yref": "paper",
                      "x": 0.99, "y": 0.99, "xanchor": "right", "font": {"size": 11, "color": "#555"}}],
    )
    return fig


def _title(title: str, label: str) -> str:
    return f"{title}<br>{label}" if title else label


def grasp_view_html(objects, grasps: Sequence[ViewGrasp], title: str = "", full_html: bool = True, height_px: int = 640, hand=None) -> str:
    """The view as HTML with plotly.js inlined: a whole page, or (``full_html=False``) a ``<div>`` to embed; ``hand`` the
    hand model of the poses (None: the Shadow Hand)."""
    import hashlib

    fig = grasp_view_figure(objects, grasps, title, hand)
    # plotly names the div with a random id unless given one: an id from the content keeps the page deterministic
    div_id = "grasp-view-" + hashlib.sha256(fig.to_json().encode()).hexdigest()[:16]
    return fig.to_html(full_html=full_html, include_plotlyjs=True, default_height=f"{height_px}px", default_width="100%",
                       config={"displaylogo": False, "responsive": True}, div_id=div_id)


def write_grasp_view(path: str | Path, objects, grasps: Sequence[ViewGrasp], title: str = "", hand=None) -> Path:
    """Write the view to ``path`` (one self-contained HTML file, written atomically) and return the path; ``hand`` the
    hand model of the poses (None: the Shadow Hand)."""
    from dexlite_pipeline.atomic import write_text_atomic

    html = grasp_view_html(objects, grasps, title, hand=hand)
    write_text_atomic(path, html)
    return Path(path)


def grasp_label(arrays: Mapping[str, np.ndarray], row: int) -> str:
    """A grasp's results in one or two lines: source or method (if any), grasp type, object, held or not, six-direction pushes,
    energies."""
    parts = [f"{type_of(arrays, row)} grasp", f"{arrays['object_id'][row]} (scale {float(arrays['scale'][row]):.3f} m)"]
    if "source" in arrays:  # dexlite grasp: which synthesis made the grasp (model or optimization)
        parts.insert(0, f"from the {arrays['source'][row]}")
    elif "method" in arrays:
        parts.insert(0, str(arrays["method"][row]))
    if "lift_success" in arrays:
        held = bool(arrays["lift_success"][row])
        text = "held" if held else "not held"
        if "lift_ratio" in arrays and np.isfinite(float(arrays["lift_ratio"][row])):
            text += f" (lift ratio {float(arrays['lift_ratio'][row]):.2f})"
        if not held and "failure_reason" in arrays and str(arrays["failure_reason"][row]):
            text += f": {arrays['failure_reason'][row]}"
        parts.append(text)
    if "six_dir_passed" in arrays:
        passed = np.asarray(arrays["six_dir_passed"][row], dtype=bool).reshape(-1)
        names = " ".join(d for d, ok in zip(SIX_DIRECTIONS, passed) if ok) or "none"
        parts.append(f"six-direction pushes held {int(passed.sum())}/6 ({names})")
    energies = []
    for key, (name, unit, fmt) in ENERGY_LABELS.items():
        if key in arrays and np.isfinite(float(arrays[key][row])):
            energies.append(f"{name} {fmt.format(float(arrays[key][row]))}{unit}")
    line = " · ".join(parts)
    return line + ("<br>" + ", ".join(energies) if energies else "")


def spread_rows(object_ids: np.ndarray, max_grasps: int) -> np.ndarray:
    """Up to ``max_grasps`` row indices, taken in turn from each object (rows of one object in order)."""
    by_object: dict[str, list[int]] = {}
    for row, oid in enumerate(object_ids):
        by_object.setdefault(str(oid), []).append(row)
    queues = list(by_object.values())
    chosen: list[int] = []
    depth = 0
    while len(chosen) < max_grasps and any(depth < len(q) for q in queues):
        chosen += [q[depth] for q in queues if depth < len(q)][: max_grasps - len(chosen)]
        depth += 1
    return np.asarray(sorted(chosen), dtype=np.int64)


def grasp_set_view(grasps, objects_dirs, max_grasps: int = DEFAULT_MAX_GRASPS, rows=None) -> tuple[dict, list[ViewGrasp]]:
    """The meshes and ``ViewGrasp``s of a ``GraspSet`` (object meshes from the prepared assets in ``objects_dirs``).

    ``rows`` chooses the grasps (default: all); those with a non-finite pose are skipped (they
    cannot be drawn); at most ``max_grasps`` are kept, spread evenly over the objects.
    """
    if isinstance(objects_dirs, (str, Path)):
        objects_dirs = [str(objects_dirs)]
    arrays = grasps.arrays
    candidates = np.arange(len(grasps)) if rows is None else np.asarray(rows, dtype=np.int64)
    candidates = candidates[np.isfinite(np.asarray(grasps.hand_pose, np.float64)[candidates]).all(axis=1)]
    chosen = candidates[spread_rows(np.asarray(grasps.object_id)[candidates], max_grasps)]
    objects: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    view: list[ViewGrasp] = []
    for row in chosen:
        key = f"{grasps.object_id[row]} @ {float(grasps.scale[row]):.4f}"
        if key not in objects:
            objects[key] = object_mesh_world([str(d) for d in objects_dirs], str(grasps.object_id[row]), float(grasps.scale[row]))
        view.append(ViewGrasp(key, np.asarray(grasps.hand_pose[row], np.float64), grasp_label(arrays, int(row))))
    return objects, view


def _shown(view: list[ViewGrasp], total: int) -> str:
    return f"{len(view)} of {total} grasps" if len(view) < total else f"{len(view)} grasp{'s' if len(view) > 1 else ''}"


def write_grasp_set_view(
    path: str | Path, grasps, objects_dirs, max_grasps: int = DEFAULT_MAX_GRASPS, title: str = "", hand=None
) -> Path | None:
    """Write ``view.html`` for a ``GraspSet`` (e.g. the held grasps of ``dexlite grasp``), drawing ``hand`` (None: the hand
    its attributes record, ``report.render.hand_of_store``); None when it has no drawable grasp."""
    objects, view = grasp_set_view(grasps, objects_dirs, max_grasps)
    if not view:
        return None
    shown = _shown(view, len(grasps))
    return write_grasp_view(path, objects, view, f"{title}: {shown}" if title else shown, hand_of_store(grasps.attrs) if hand is None else hand)


def grasp_view_div(grasps, rows, objects_dirs, max_grasps: int = 2 * DEFAULT_MAX_GRASPS, height_px: int = 560) -> str | None:
    """The view of the chosen ``rows`` as an HTML ``<div>`` with plotly.js inlined, to embed in a page; None when none is
    drawable. The hand drawn is the one the grasps' attributes record (``report.render.hand_of_store``)."""
    objects, view = grasp_set_view(grasps, objects_dirs, max_grasps, rows=rows)
    if not view:
        return None
    return grasp_view_html(objects, view, _shown(view, len(rows)), full_html=False, height_px=height_px, hand=hand_of_store(grasps.attrs))
