"""The summary of a ``dexlite grasp`` run: one row of counts per object (size, held, distinct, surface touched,
failure reasons), the counts of each source (model, optimization from scratch) and of each grasp type, what to try
next, and the one-page ``summary.md`` that shows them."""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dexlite_pipeline.io.grasp_store import DEFAULT_GRASP_TYPE, grasp_types
from dexlite_pipeline.model.config import ANY_GRASP_TYPE
from dexlite_pipeline.tools.grasp.request import SOURCE_MODEL, SOURCE_OPTIMIZATION, UNIT_NAMES, WANTED_DISTINCT, GraspRequest
from dexlite_pipeline.tools.grasp.selection import distinct_labels, distinct_per_object

if TYPE_CHECKING:
    from dexlite_pipeline.evaluation.config import DiversityConfig
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.objects.sources import MeshSource
    from dexlite_pipeline.settings import PipelineConfig
    from dexlite_pipeline.sim.config import LiftConfig
    from dexlite_pipeline.tools.grasp.checks import MeshSize


def failure_counts(reasons) -> dict[str, int]:
    """Failure reasons of grasps that did not hold, most frequent first ('initial_penetration' -> 'initial penetration')."""
    counts = Counter(str(r).replace("_", " ") if r else "dropped" for r in reasons)
    return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def per_object_rows(
    grasps: GraspSet, labels: np.ndarray, sources: list[MeshSource], sizes: dict[str, MeshSize], prepared_ids: list[str],
    coverage: dict[str, float] | None = None,
) -> list[dict]:
    """One summary row per prepared object: its size, counts held / distinct, the share of its surface the held
    grasps touch (``coverage``: object id -> share, NaN when not measured) and the failure reasons."""
    rows = []
    file_of = {s.object_id: s.file for s in sources}
    held_all = np.asarray(grasps.arrays["lift_success"], bool)
    six_all = np.asarray(grasps.arrays["six_dir_success"], bool)
    for object_id in prepared_ids:
        mask = grasps.object_id == object_id
        lift, six = held_all[mask], six_all[mask]
        reasons = np.asarray(grasps.arrays["failure_reason"], dtype=object)[mask & ~held_all]
        start = np.asarray(grasps.arrays.get("initial_penetration_mm", np.full(len(grasps), np.nan)), np.float64)[mask & held_all]
        rows.append({
            "object_id": object_id, "file": file_of.get(object_id, ""), "size": sizes.get(object_id),
            "radii_m": sorted({round(float(s), 4) for s in grasps.scale[mask]}), "grasps": int(mask.sum()),
            "lift": int(lift.sum()), "six_dir": int(six.sum()), "both": int((lift & six).sum()),
            "distinct": len(set(labels[mask & held_all].tolist())), "failures": failure_counts(reasons),
            "coverage": (coverage or {}).get(object_id, math.nan),
            "start_depth_max_mm": float(np.nanmax(start)) if np.isfinite(start).any() else math.nan,
        })  # fmt: skip
    return rows


def preparation_text(meta: dict) -> str:
    """How a prepared object's solid was made from its file and how far it is from the file's surface (its meta.json)."""
    notes = "".join(f"; {note}" for note in meta["preparation"].get("notes", []))
    return f"{meta['preparation']['summary']}{notes}; prepared solid vs the mesh: {meta['deviation']['summary']}"


def per_group_counts(grasps: GraspSet, config: PipelineConfig, groups: np.ndarray) -> dict[str, dict[str, dict[str, int]]]:
    """Object id -> group -> attempts, held and distinct held grasps among that group's grasps alone (``groups`` (N,):
    each grasp's source, or its grasp type)."""
    groups = np.asarray([str(g) for g in groups], dtype=object)
    held = np.asarray(grasps.arrays["lift_success"], bool)
    counts: dict[str, dict[str, dict[str, int]]] = {}
    for group in dict.fromkeys(groups.tolist()):
        part = grasps.select(np.flatnonzero(groups == group))
        distinct = distinct_per_object(part, distinct_labels(part, config))
        for object_id in dict.fromkeys(part.object_id.tolist()):
            mask = (grasps.object_id == object_id) & (groups == group)
            counts.setdefault(object_id, {})[group] = {"grasps": int(mask.sum()), "held": int(held[mask].sum()), "distinct": distinct[object_id]}
    return counts


def per_source_counts(grasps: GraspSet, config: PipelineConfig) -> dict[str, dict[str, dict[str, int]]]:
    """Object id -> source -> attempts, held and distinct held grasps among that source's grasps alone."""
    return per_group_counts(grasps, config, grasps.arrays["source"])


def per_type_counts(grasps: GraspSet, config: PipelineConfig) -> dict[str, dict[str, dict[str, int]]]:
    """Object id -> grasp type -> attempts, held and distinct held grasps of that type alone (power for grasps without one)."""
    return per_group_counts(grasps, config, grasp_types(grasps))


def _size_text(size: MeshSize) -> str:
    """'9.5 x 8 x 10 cm' from the oriented extents."""
    return " x ".join(f"{100 * e:.3g}" for e in size.oriented_m) + " cm"


def _depth(mm: float) -> str:
    return "-" if mm != mm else f"{mm:.1f}"


def _percent(share: float) -> str:
    return "-" if share != share else f"{100 * share:.0f}%"


def share_text(count: int, total: int) -> str:
    """'3/8 (38%)': ``count`` of ``total`` with its percentage ('0/0' when there is none)."""
    return f"{count}/{total} ({100 * count / total:.0f}%)" if total else "0/0"


def next_steps(request: GraspRequest, rows: list[dict], rejected: list[dict]) -> list[str]:
    """What to try next, each from a fact of this run: objects with fewer than ``WANTED_DISTINCT`` distinct held grasps
    (why, from their failure reasons and sources) and meshes not tried for their size. Empty when there is nothing to suggest."""
    hints = []
    more = f"more grasps (`--n {2 * request.grasps_per_object}`)"
    if request.model and request.min_distinct > 0:
        more = f"more top-up batches (`--top-up-batches {2 * request.top_up_batches}`) or " + more
    top_up = f"`--min-distinct {WANTED_DISTINCT}`"
    for r in rows:
        if r["distinct"] >= WANTED_DISTINCT:
            continue
        failed = r["grasps"] - r["lift"]
        facts = [f"{r['distinct']} distinct held grasp(s) of {r['grasps']}"]
        if r.get("topped_up"):
            facts[0] += " from the model and optimization from scratch together"
        if r["lift"] > r["distinct"]:
            facts.append(f"its {r['lift']} held grasps are near-duplicates of {r['distinct']}")
        top, count = next(iter(r["failures"].items()), ("", 0))
        untried = request.model and not r.get("topped_up")  # optimization from scratch has not run on this object
        if failed and top == "initial penetration" and 2 * count >= failed:
            facts.append(f"{count} of the {failed} failures start with the hand inside the object")
            fix = f"{top_up} (optimization from scratch tops up the model's grasps and pushes the hand out of the object) or {more}" if untried else more
        else:
            if failed:
                facts.append(f"the most common failure is '{top}' ({count} of {failed})")
            fix = f"{more} or {top_up} (optimization from scratch tops up the model's grasps with other grasps)" if untried else more
        hints.append(f"`{Path(r['file']).name}`: " + "; ".join(facts) + f": try {fix}.")
    for r in rejected:
        if r.get("kind") == "hand_fit":
            hints.append(f"`{Path(r['file']).name}` was not tried ({r['reason']}); if its file is not in "
                         f"{UNIT_NAMES[request.units]}, give its unit with `--units`.")
    return hints


def source_lines(request: GraspRequest, rows: list[dict]) -> list[str]:
    """The summary's section on the two sources of a model run: per object held and distinct held grasps of the model
    and of optimization from scratch (each counted alone), and whether and why optimization topped the model up."""
    if not request.model:
        return []
    lines = [
        "", "## Model and optimization from scratch", "",
        "| object | model: held | model: distinct held | optimization from scratch: held | optimization from scratch: distinct held | distinct held, together |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
    ]  # fmt: skip
    none = {"grasps": 0, "held": 0, "distinct": 0}
    for r in rows:
        model = r.get("by_source", {}).get(SOURCE_MODEL, none)
        optimized = r.get("by_source", {}).get(SOURCE_OPTIMIZATION)
        scratch = (share_text(optimized["held"], optimized["grasps"]), optimized["distinct"]) if optimized else ("not run", "-")
        lines.append(f"| {r['object_id']} | {share_text(model['held'], model['grasps'])} | {model['distinct']} | {scratch[0]} | {scratch[1]} "
                     f"| {r['distinct']} |")
    lines.append("")
    if request.min_distinct == 0:
        lines.append("`--min-distinct 0`: the model's grasps only; optimization from scratch never tops them up.")
        return lines
    for r in rows:
        model = r.get("by_source", {}).get(SOURCE_MODEL, none)
        optimized = r.get("by_source", {}).get(SOURCE_OPTIMIZATION)
        name = f"`{Path(r['file']).name}`"
        if r.get("topped_up") and optimized:
            lines.append(f"- {name}: the model gave {model['distinct']} distinct held grasp(s) < {request.min_distinct} (`--min-distinct`): "
                         f"optimization from scratch added {optimized['grasps']} grasps in "
                         f"{-(-optimized['grasps'] // max(1, request.grasps_per_object))} batch(es) of at most {request.top_up_batches}, "
                         f"{optimized['held']} held, {optimized['distinct']} distinct; "
                         f"{r['distinct']} distinct held grasp(s) together.")  # fmt: skip
        else:
            lines.append(f"- {name}: the model gave {model['distinct']} distinct held grasp(s), at least {request.min_distinct} "
                         "(`--min-distinct`): no optimization from scratch.")  # fmt: skip
    return lines


def type_lines(request: GraspRequest, rows: list[dict]) -> list[str]:
    """The summary's section on grasp types: per object and type the grasps tried, held and distinct held, when the grasps
    hold several types or one was asked for (``--grasp-type``); nothing for power grasps only, as asked."""
    types = list(dict.fromkeys(t for r in rows for t in r.get("by_type", {})))
    if not types or (types == [DEFAULT_GRASP_TYPE] and request.grasp_type == ANY_GRASP_TYPE):
        return []
    asked = "any type (the model's training mix)" if request.grasp_type == ANY_GRASP_TYPE else f"{request.grasp_type} grasps only"
    lines = ["", "## Grasp types", "", f"Asked for {asked} (`--grasp-type {request.grasp_type}`).", "",
             "| object | grasp type | grasps | held | distinct held |", "| --- | --- | ---: | ---: | ---: |"]  # fmt: skip
    for r in rows:
        for name, c in r.get("by_type", {}).items():
            lines.append(f"| {r['object_id']} | {name} | {c['grasps']} | {share_text(c['held'], c['grasps'])} | {c['distinct']} |")
    return lines


def summary_markdown(
    request: GraspRequest, rows: list[dict], rejected: list[dict], method: str, step_seconds: dict[str, float], renders: list[Path],
    lift_config: LiftConfig, diversity: DiversityConfig, kept: int, view: Path | None = None, hand_note: str = "",
) -> str:
    """The one-page ``summary.md``: per object its size, held and distinct counts, failure reasons; what to try next.
    ``hand_note``: a line on a hand other than the Shadow Hand (``run.hand_note``), after the first paragraph."""
    total = sum(r["grasps"] for r in rows)
    lift, six, both, distinct = (sum(r[k] for r in rows) for k in ("lift", "six_dir", "both", "distinct"))
    seconds = sum(step_seconds.values())
    size_rule = ("each object resized to the training radii" if request.resize_to_training
                 else f"each object at its real size (mesh units: {request.units})")  # fmt: skip
    lines = [
        "# Grasps",
        "",
        f"**{share_text(lift, total)} grasps held the object in the lift test, {distinct} of them distinct; {share_text(both, total)} also "
        f"passed the six-direction test** ({len(rows)} object(s), {size_rule}, {method}, {seconds / 60:.1f} min).",
        "",
        f"A grasp *holds* when it starts at most {1000 * lift_config.max_initial_penetration_m:g} mm inside the object (measured "
        f"against its mesh, both ways) and the hand lifts the object {lift_config.lift_height_m:g} m and keeps at least "
        f"{100 * lift_config.success_lift_ratio:.0f}% of that rise (MuJoCo, object {lift_config.object_mass_kg:g} kg, "
        f"friction {lift_config.friction:g}); the six-direction test pushes the held object with "
        f"{lift_config.six_dir_force_per_kg_n:g} N/kg along ±x, ±y, ±z (gravity off) and passes when it moves less than "
        f"{100 * lift_config.six_dir_max_translation_m:g} cm and turns less than {lift_config.six_dir_max_rotation_deg:g}° each time. "
        f"Two held grasps are *the same grasp* when their palms are within {100 * diversity.distinct_translation_m:g} cm "
        f"and {diversity.distinct_rotation_deg:g}° of each other. *Surface touched*: the share of the object's surface, cut into "
        f"{diversity.coverage_patches} patches of about equal area, that the held grasps' contact points (hand surface points within "
        f"{1000 * diversity.coverage_contact_m:g} mm of the object) reach.",
        "",
    ]
    if hand_note:
        lines += [hand_note, ""]
    if kept:
        what = "one of each distinct held grasp (the best)" if request.distinct else "every held grasp"
        lines.append(f"`grasps.zarr` and `dexgraspnet/` hold {what}: {kept} grasp(s). `all_grasps.zarr` holds all {total} with their failure reasons.")
    else:
        lines.append(f"No grasp held: `grasps.zarr` is empty and no `dexgraspnet/` was written. `all_grasps.zarr` holds all {total} with their failure reasons.")
    lines += [
        "",
        "| object | file | size (cm) | grasps | held | distinct held | deepest start of a held grasp (mm) | surface touched | six-direction passed "
        "| held and six-direction passed | why the others failed |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in rows:
        size = _size_text(r["size"]) if r["size"] is not None and not request.resize_to_training else (
            "radius " + ", ".join(f"{100 * s:.3g}" for s in r["radii_m"]))
        reasons = ", ".join(f"{reason} {count}" for reason, count in r["failures"].items()) or "-"
        lines.append(f"| {r['object_id']} | {Path(r['file']).name} | {size} | {r['grasps']} | {share_text(r['lift'], r['grasps'])} | "
                     f"{r['distinct']} | {_depth(r.get('start_depth_max_mm', math.nan))} | {_percent(r.get('coverage', math.nan))} | "
                     f"{share_text(r['six_dir'], r['grasps'])} | {share_text(r['both'], r['grasps'])} | {reasons} |")
    lines.append(f"| **all** | | | {total} | {share_text(lift, total)} | {distinct} | | | {share_text(six, total)} | {share_text(both, total)} | |")
    lines += source_lines(request, rows)
    lines += type_lines(request, rows)
    lines += ["", "## How each mesh was prepared", "",
              "Each mesh becomes one closed solid, checked against the mesh's own surface (two-sided surface distance p99, "
              "bounding box, volume where the mesh is closed, as percentages of its largest extent); a solid farther from the mesh "
              "than the tolerance is refused, not grasped.", ""]  # fmt: skip
    lines += [f"- {r['object_id']}: {r.get('prepared_as', '-')}" for r in rows]
    if rejected:
        lines += ["", "## Meshes not tried", ""]
        lines += [f"- `{r['file']}`: {r['reason']}" for r in rejected]
    hints = next_steps(request, rows, rejected)
    if hints:
        lines += ["", "## What to try next", ""] + [f"- {h}" for h in hints]
    if view is not None:
        lines += ["", f"Open `{view.name}` in a browser to turn each kept grasp around (one file, works offline)."]
    if renders:
        lines += ["", "## Examples (different grasps)", ""]
        lines += [f"![{p.stem}](renders/{p.name})" for p in renders]
    lines += ["", "## Run", "", "| step | seconds |", "| --- | ---: |"]
    lines += [f"| {name} | {value:.0f} |" for name, value in step_seconds.items()]
    lines += [
        "",
        f"Grasps per object: {request.grasps_per_object}; size: {size_rule}; distinct only: {'yes' if request.distinct else 'no'}; "
        f"model: {request.model or 'none (optimization from scratch)'}"
        + (f"; min distinct: {request.min_distinct} (`--min-distinct`)." if request.model else "."),
        "",
    ]
    return "\n".join(lines)
