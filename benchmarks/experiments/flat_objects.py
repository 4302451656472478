"""Why objects lying flat on a table get no grasp: their height against the fingertips, and what ends each grasp.

    python benchmarks/experiments/flat_objects.py profile household-spoon-003 [household-pliers-004 ...]
    python benchmarks/experiments/flat_objects.py grasps RUN_DIR [RUN_DIR ...] [--contact-normals]

``profile``: per household object (generated in metres, standing on z = 0), its height on the table, and where a
fingertip could squeeze it from the side: the share of its surface facing sideways (outward normal within 30° of the
table's plane) and how high that surface reaches, against the radii of the Shadow Hand's distal capsules (read from the
hand model: 7.05 mm for the fingers, 9.18 mm for the thumb). A fingertip standing on the table touches a vertical side
with a horizontal normal only at its capsule's radius above the table or higher; on a lower side its spherical end
meets the object's top edge, pushing it down into the table.

``grasps``: every ``all_grasps.zarr`` under the given folders (``grasp_types.py`` runs, ``dexlite grasp`` outputs),
per household family and grasp type: attempts, those stopped early as hopeless, the energy terms at the end (p10 / p50
/ p90: E_fc, E_dis and E_pen in mm, the judged penetration depth), the first of curation's energy thresholds each grasp
fails (``curation.filters.threshold_reasons``: e_fc, e_dis, e_pen, penetration_mm; "within" for none), the lift test's
result and failure reasons, and the heights of the four contact points above the table (all, and each grasp's lowest).
``--contact-normals`` adds, for the grasps the lift test simulated, the direction in which MuJoCo's contacts between
the hand and the object (its convex pieces) push at the grasp pose, before the fingers close: the angle of each
contact's push below the table's plane (0: horizontal, 90: straight down onto the object's top), the median over a
grasp's contacts, then p10 / p50 / p90 over the grasps; with friction 0.6 a push more than 31° below the plane cannot
carry the object's weight up by friction.
"""

from __future__ import annotations

import argparse
import math
from collections import Counter
from pathlib import Path

import numpy as np

SIDE_DEG = 30.0  # a surface facing sideways: outward normal within this angle of the table's plane
FRICTION_CONE_DEG = math.degrees(math.atan(0.6))  # the lift test's friction 0.6: 31.0°


def fingertip_radii() -> dict[str, float]:
    """The radii (m) of the Shadow Hand's index and thumb distal capsules, by link."""
    from dexlite_pipeline.hand.model import ShadowHand

    hand = ShadowHand()
    return {link: float(hand.shape_size[hand._capsule_of_link(f"robot0:{link}"), 0]) for link in ("ffdistal", "thdistal")}


def height_profile(mesh, radii: dict[str, float], samples: int = 40000, seed: int = 0) -> dict:
    """Height (m) of ``mesh`` (metres, +z up, resting on its lowest point) and its sideways-facing surface: the share of
    the area, the p50 / p90 / max height of that surface above the table (m, NaN without any), and per fingertip the
    share of it higher than that fingertip's radius (where the fingertip can touch it with a horizontal normal)."""
    import trimesh

    points, faces = trimesh.sample.sample_surface(mesh, samples, seed=seed)
    floor = float(mesh.bounds[0, 2])
    height = points[:, 2] - floor
    side = np.abs(np.asarray(mesh.face_normals)[faces, 2]) < math.sin(math.radians(SIDE_DEG))
    heights = height[side]
    quantiles = np.percentile(heights, [50, 90]).tolist() + [float(heights.max())] if len(heights) else [math.nan] * 3
    return {"height_m": float(mesh.bounds[1, 2] - floor), "side_share": float(side.mean()), "side_height_m": quantiles,
            "side_above": {link: float((heights > r).mean()) if len(heights) else 0.0 for link, r in radii.items()}}  # fmt: skip


def profile_table(object_ids: list[str]) -> list[str]:
    from dexlite_pipeline.objects.household import household_object

    radii = fingertip_radii()
    lines = ["| object | height mm | extent mm | sideways-facing area % | its height p50 / p90 / max mm | "
             + " | ".join(f"of it above the {link} radius {1000 * r:.2f} mm %" for link, r in radii.items()) + " |",
             "| --- | ---: | ---: | ---: | ---: | " + " | ".join("---:" for _ in radii) + " |"]  # fmt: skip
    for object_id in object_ids:
        mesh = household_object(object_id).mesh
        p = height_profile(mesh, radii)
        extent = 1000 * (mesh.bounds[1] - mesh.bounds[0])
        lines.append(f"| {object_id} | {1000 * p['height_m']:.1f} | {extent[0]:.0f} x {extent[1]:.0f} | {100 * p['side_share']:.0f} | "
                     + " / ".join(f"{1000 * h:.1f}" for h in p["side_height_m"]) + " | "
                     + " | ".join(f"{100 * p['side_above'][link]:.0f}" for link in radii) + " |")  # fmt: skip
    return lines


def contact_heights_m(grasps) -> np.ndarray:
    """(B, 4) height (m) above each grasp's table of its four contact points (the contact table's points it names)."""
    import torch

    from dexlite_pipeline.hand.model import ShadowHand

    hand = ShadowHand()
    frames = hand.forward(torch.as_tensor(np.asarray(grasps.hand_pose, np.float32)))
    table = frames.transform(hand.all_contact_points_local, hand.all_contact_link).double().numpy()
    index = np.asarray(grasps.arrays["contact_index"], np.int64)
    points = np.take_along_axis(table, index[..., None], axis=1)
    normal, offset = np.asarray(grasps.arrays["support_normal"], np.float64), np.asarray(grasps.arrays["support_offset_m"], np.float64)
    return np.einsum("bkj,bj->bk", points, normal) + offset[:, None]


def push_angles_deg(run: Path, grasps, rows: np.ndarray) -> np.ndarray:
    """(len(rows),) per grasp the median angle (degrees) below the table's plane at which MuJoCo's hand-object contacts
    push the object at the grasp pose (module docstring); NaN where the hand touches no convex piece there."""
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.objects.rest_pose import SupportPlane
    from dexlite_pipeline.sim.config import LiftConfig
    from dexlite_pipeline.sim.scene import LiftScene
    from dexlite_pipeline.sim.simulator import GraspSimulator, _palm_quaternions

    config, simulators, out = LiftConfig(), {}, np.full(len(rows), np.nan)
    for k, i in enumerate(rows):
        object_id, scale = str(grasps.object_id[i]), float(grasps.scale[i])
        normal = np.asarray(grasps.arrays["support_normal"][i], np.float64)
        key = (object_id, scale)
        if key not in simulators:
            table = SupportPlane(tuple(normal.tolist()), float(grasps.arrays["support_offset_m"][i]) / scale)
            asset = load_asset([str(run / "objects")], object_id)
            simulators[key] = GraspSimulator(LiftScene.build(asset.convex_paths, scale, config, table), config)
        sim = simulators[key]
        pose = np.asarray(grasps.hand_pose[i], np.float64)
        sim._reset(pose, _palm_quaternions(pose[None])[0])
        scene, model, data = sim.scene, sim.scene.model, sim.scene.data
        angles = []
        for c in range(data.ncon):
            contact = data.contact[c]
            b1, b2 = model.geom_bodyid[contact.geom1], model.geom_bodyid[contact.geom2]
            if scene.object_body in (b1, b2) and 0 not in (b1, b2) and b1 != b2:
                push = np.asarray(contact.frame[:3]) * (1.0 if b2 == scene.object_body else -1.0)  # from the hand into the object
                angles.append(math.degrees(math.asin(float(np.clip(-push @ normal, -1.0, 1.0)))))
        out[k] = np.median(angles) if angles else np.nan
    return out


def _q(values) -> str:
    values = np.asarray(values, np.float64)
    values = values[np.isfinite(values)]
    return " / ".join(f"{v:.2f}" for v in np.percentile(values, [10, 50, 90])) if len(values) else "-"


def grasp_table(runs: list[Path], contact_normals: bool = False) -> list[str]:
    from dexlite_pipeline.curation.config import CurateConfig
    from dexlite_pipeline.curation.filters import threshold_reasons
    from dexlite_pipeline.io.grasp_store import grasp_types, read_grasp_store
    from dexlite_pipeline.objects.household import parse_household_id

    groups: dict[tuple[str, str], dict[str, list]] = {}
    for root in runs:
        for store in sorted(root.rglob("all_grasps.zarr")):
            grasps = read_grasp_store(store)
            a = grasps.arrays
            reasons = threshold_reasons(grasps, CurateConfig())
            heights = 1000 * contact_heights_m(grasps)
            family = np.asarray([parse_household_id(str(o).removeprefix("user-"))[0] for o in grasps.object_id], dtype=object)
            types = grasp_types(grasps)
            simulated = np.isfinite(np.asarray(a["lift_ratio"], np.float64))
            push = np.full(len(grasps), np.nan)
            if contact_normals:
                push[simulated] = push_angles_deg(store.parent, grasps, np.nonzero(simulated)[0])
            for key in sorted(set(zip(family.tolist(), types.tolist()))):
                mine = (family == key[0]) & (types == key[1])
                g = groups.setdefault(key, {k: [] for k in ("fc", "dis", "pen", "depth", "stop", "reason", "held", "fail", "h", "low", "push")})
                g["fc"] += a["E_fc"][mine].tolist()
                g["dis"] += (1000 * np.asarray(a["E_dis"][mine])).tolist()
                g["pen"] += (1000 * np.asarray(a["E_pen"][mine])).tolist()
                g["depth"] += a["penetration_mm"][mine].tolist()
                g["stop"] += (np.asarray(a["stopped_at_iteration"][mine]) > 0).tolist()
                g["reason"] += [r or "within" for r in reasons[mine]]
                g["held"] += np.asarray(a["lift_success"][mine], bool).tolist()
                g["fail"] += [str(r).split(":")[0] for r, ok in zip(a["failure_reason"][mine], a["lift_success"][mine]) if not ok]
                g["h"] += heights[mine].ravel().tolist()
                g["low"] += heights[mine].min(1).tolist()
                g["push"] += push[mine & simulated].tolist()
    lines = ["| family | type | attempts | stopped early | E_fc | E_dis mm | E_pen mm | depth mm | first threshold failed | held (lift) "
             "| lift failures | contact height mm | lowest contact mm |" + (" contact push below the table's plane, deg (grasps) |" if contact_normals else ""),
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | --- | ---: | ---: |" + (" ---: |" if contact_normals else "")]  # fmt: skip
    for (family, grasp_type), g in groups.items():
        reasons = ", ".join(f"{r} {n}" for r, n in Counter(g["reason"]).most_common())
        fails = ", ".join(f"{r} {n}" for r, n in Counter(g["fail"]).most_common(3))
        push = f" {_q(g['push'])} ({int(np.isfinite(g['push']).sum())}) |" if contact_normals else ""
        lines.append(f"| {family} | {grasp_type} | {len(g['fc'])} | {sum(g['stop'])} | {_q(g['fc'])} | {_q(g['dis'])} | {_q(g['pen'])} | "
                     f"{_q(g['depth'])} | {reasons} | {sum(g['held'])} | {fails} | {_q(g['h'])} | {_q(g['low'])} |{push}")  # fmt: skip
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    profile = commands.add_parser("profile", help="height profiles of household objects against the fingertips")
    profile.add_argument("object_ids", nargs="+")
    grasps = commands.add_parser("grasps", help="what ended the grasps of grasp_types.py runs or dexlite grasp outputs")
    grasps.add_argument("runs", nargs="+", type=Path)
    grasps.add_argument("--contact-normals", action="store_true", help="also MuJoCo's contact directions at the grasp pose")
    args = parser.parse_args(argv)
    lines = profile_table(args.object_ids) if args.command == "profile" else grasp_table(args.runs, args.contact_normals)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
