"""The dataset's data card, CARD.md: regenerated from the tables and grasps, never edited by hand.

Deterministic (no date of writing, rows in table order), so it changes in git only when the data does.
"""

from __future__ import annotations

import os
from pathlib import Path

from dexlite_pipeline.atomic import write_text_atomic
from dexlite_pipeline.dataset.layout import (
    BATCHES_TABLE, CARD_NAME, CONFIGS_DIR, DISTINCT_ROTATION_DEG, DISTINCT_TRANSLATION_M, GRASP_TYPE_ABSENT, GRASPS_DIR, OBJECT_COLUMNS,
    OBJECTS_TABLE, STORED_ARRAYS, TARGET_DISTINCT_PER_OBJECT, TARGET_OBJECTS,
)  # fmt: skip
from dexlite_pipeline.dataset.hand import HAND_MEMBERS
from dexlite_pipeline.dataset.summary import dataset_summary

# Bins of the per-object distribution of distinct held grasps: (label, lowest, highest or None).
DISTINCT_BINS = (("0", 0, 0), ("1-9", 1, 9), ("10-29", 10, 29), ("30-99", 30, 99), ("100 or more", 100, None))
PROGRESS_BAR_WIDTH = 40


def _percent(part: float, whole: float) -> str:
    return f"{100.0 * part / whole:.1f}%" if whole else "n/a"


def _table(header: list[str], rows: list[list]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(" --- " for _ in header) + "|"]
    lines += ["| " + " | ".join(str(cell).replace("|", "\\|") for cell in row) + " |" for row in rows]
    return lines


def _spread_text(spread: dict) -> str:
    return f"{spread['min']} / {spread['median']:g} / {spread['max']}"


def _progress(summary: dict) -> list[str]:
    target = summary["target"]
    done = target["household_training_objects_at_target"]
    filled = min(PROGRESS_BAR_WIDTH, round(PROGRESS_BAR_WIDTH * done / TARGET_OBJECTS))
    return [
        "## Progress toward the target",
        "",
        f"The campaign's target: at least {TARGET_OBJECTS} household training objects with at least "
        f"{TARGET_DISTINCT_PER_OBJECT} distinct held grasps each.",
        "",
        f"**{done} of {TARGET_OBJECTS} household training objects reach {TARGET_DISTINCT_PER_OBJECT} distinct held grasps "
        f"({_percent(done, TARGET_OBJECTS)})**  ",
        f"`[{'#' * filled}{'.' * (PROGRESS_BAR_WIDTH - filled)}]`",
        "",
        f"Household training objects in the dataset: {target['household_training_objects']}; training objects of any "
        f"source at the target: {target['training_objects_at_target']}.",
        "",
    ]


def _distribution(summary: dict) -> list[str]:
    per_object = summary["per_object"]
    rows = []
    for label, low, high in DISTINCT_BINS:
        count = sum(low <= e["distinct_held"] and (high is None or e["distinct_held"] <= high) for e in per_object.values())
        rows.append([label, count, _percent(count, len(per_object))])
    families = [[name, f["objects"], f["grasps"], f["held"], f["distinct_held"], _spread_text(f["distinct_held_per_object"]),
                 f["objects_at_target"]] for name, f in summary["per_family"].items()]  # fmt: skip
    objects = [[object_id, e["family"], e["split"], e["grasps"], e["held"], e["distinct_held"]] for object_id, e in per_object.items()]
    return [
        "## Distinct held grasps per object",
        "",
        f"Per object (min / median / max): {_spread_text(summary['distinct_held_per_object'])}.",
        "",
        *_table(["distinct held grasps", "objects", "share"], rows),
        "",
        "Per family (household objects by family, other objects by source):",
        "",
        *_table(["family", "objects", "grasps", "held", "distinct held", "distinct per object (min / median / max)",
                 f"objects with >= {TARGET_DISTINCT_PER_OBJECT}"], families),  # fmt: skip
        "",
        "<details><summary>Every object</summary>",
        "",
        *_table(["object", "family", "split", "grasps", "held", "distinct held"], objects),
        "",
        "</details>",
        "",
    ]


def _grasp_types(summary: dict) -> list[str]:
    """The per-type table: grasps, held and distinct held grasps of each grasp type, and objects holding one."""
    rows = [[name, t["grasps"], t["held"], _percent(t["held"], t["grasps"]), t["distinct_held"], t["objects_with_held"]]
            for name, t in summary["per_type"].items()]  # fmt: skip
    return [
        "## Grasp types",
        "",
        "The type each grasp was made as (`grasp_type`: power, pinch, tripod or lateral, `optimize_grasps.grasp_types`). "
        f"Batches without `grasp_type` were made before grasp types existed, with the power template only: their grasps "
        f"count as `{GRASP_TYPE_ABSENT}`. A distinct held grasp of a type is one of an object's distinct labels among the "
        "type's held grasps.",
        "",
        *_table(["type", "grasps", "held", "held share", "distinct held", "objects with a held grasp"], rows),
        "",
    ]


def _batches(summary: dict) -> list[str]:
    rows = [[b["batch"], b["kind"], b["n_objects"], b["objects"], b["grasps"], b["held"], b["distinct_held_added"],
             f"{b['cpu_seconds_total'] / 3600.0:.2f}", b["machine"], b["code_version"][:12], b["config_digest"],
             b["started_utc"], b["finished_utc"]] for b in summary["per_batch"]]  # fmt: skip
    return [
        "## Batches",
        "",
        "CPU time per stage is in batches.csv (`cpu_seconds`, JSON); each batch's full config is in configs/.",
        "",
        *_table(["batch", "kind", "objects", "object ids", "grasps", "held", "new distinct held", "CPU hours", "machine",
                 "code version", "config digest", "started (UTC)", "finished (UTC)"], rows),  # fmt: skip
        "",
    ]


def _layout() -> list[str]:
    arrays = [[f"`{name}`", spec.kind, str(("N", *spec.trailing_shape)).replace("'", ""), spec.meaning]
              for name, spec in STORED_ARRAYS.items()]  # fmt: skip
    return [
        "## Layout",
        "",
        *_table(["path", "what"], [
            [f"`{CARD_NAME}`", "this card (generated)"],
            [f"`{OBJECTS_TABLE}`", "one row per object: " + ", ".join(OBJECT_COLUMNS)],
            [f"`{BATCHES_TABLE}`", "one row per batch: kind, objects, counts, code version, config digest, machine, CPU seconds, times, protocol"],
            [f"`{CONFIGS_DIR}/batch_NNNN.json`", "the full config of batch NNNN"],
            [f"`{GRASPS_DIR}/batch_NNNN.npz`", "every grasp batch NNNN tried, held or not (arrays below; strings as fixed-width unicode)"],
        ]),  # fmt: skip
        "",
        "Grasp arrays (N grasps per batch file; `support_normal` and `support_offset_m` only in tabletop batches, "
        "`grasp_type` only in batches made since grasp types existed):",
        "",
        *_table(["array", "dtype", "shape", "meaning"], arrays),
        "",
        "One hand per dataset: a batch of a hand other than the Shadow Hand also holds "
        + ", ".join(f"`{m}`" for m in HAND_MEMBERS)
        + " (the hand's name or MJCF file, its joints in pose order, the file's SHA-256), and its `hand_pose` is 6 + J numbers "
        "(palm position, xyz Euler angles, the J joints); a batch without them is the Shadow Hand's (28 numbers). A batch "
        "of another hand than the dataset's is refused (`dexlite_pipeline.dataset.hand`).",
        "",
        "`rebuild` in objects.csv says what rebuilds an object's mesh: `household:<object_id>` "
        "(`dexlite_pipeline.objects.household.household_object`), `pybullet_data:<file>` (a file of the pybullet_data "
        "package), or empty when the mesh is not shipped. The support plane (`support_nx/ny/nz`, `support_offset` per unit "
        "of scale) is the table under the object in its frame (`dexlite_pipeline.tabletop`).",
        "",
    ]


def _hand_lines(record: dict) -> tuple[str, str]:
    """Who the grasps are of and the shape of ``grasps.hand_pose``, for the dataset's hand record ({}: the Shadow Hand)."""
    if not record:
        return "the Shadow Hand", "(N, 28) float32: palm position (m), xyz Euler angles (rad), 22 joints (rad)"
    joints = record["joint_names"]
    return (f"the hand `{record['hand']}` (joints {', '.join(joints)})",
            f"(N, {6 + len(joints)}) float32: palm position (m), xyz Euler angles (rad), {len(joints)} joints (rad)")


def card_text(dataset_dir: str | os.PathLike, protocol_text: str) -> str:
    """The Markdown of CARD.md for the dataset at ``dataset_dir`` (its hand: ``dataset.hand``)."""
    from dexlite_pipeline.dataset.store import stored_hand

    summary = dataset_summary(dataset_dir)
    hand_text, pose_text = _hand_lines(stored_hand(dataset_dir))
    objects, grasps, held = summary["objects"], summary["grasps"], summary["held"]
    cpu_hours = sum(b["cpu_seconds_total"] for b in summary["per_batch"]) / 3600.0
    lines = [
        "# DexLite tabletop grasp dataset",
        "",
        "_Generated from the dataset's tables and grasps by `dexlite_pipeline.dataset.card.write_card`; "
        "do not edit by hand (the next batch rewrites it)._",
        "",
        "## What it is",
        "",
        f"Grasps of {hand_text} on objects standing on a table, made by the DexLite pipeline (energy optimization, "
        "a CVAE generator and data-loop rounds) and tested in MuJoCo. A grasp is *held* (`lift_success`) when the object "
        "stays in the hand as it is lifted off its table. Every grasp a batch tried is kept, held or not, with its "
        "energies and outcome. Held grasps carry a `distinct_label`, consistent over the whole dataset: two grasps of one "
        f"object and scale are the same grasp when their palms are within {DISTINCT_TRANSLATION_M * 100:g} cm and "
        f"{DISTINCT_ROTATION_DEG:g} deg of each other, so an object's distinct held grasps are its number of labels.",
        "",
        "## How to load",
        "",
        "```python",
        "from dexlite_pipeline.dataset import load_dataset",
        "",
        'grasps, objects = load_dataset("path/to/dataset", held_only=True)  # GraspSet, pandas.DataFrame',
        f"grasps.hand_pose            # {pose_text}",
        'grasps.arrays["distinct_label"]  # (N,) int32, per object',
        "```",
        "",
        "Without the project: `numpy.load(\"grasps/batch_0001.npz\")` (no pickle needed) and `pandas.read_csv(\"objects.csv\")`.",
        "",
        "## Totals",
        "",
        *_table(["", ""], [
            ["objects", f"{objects} ({summary['objects_by_split']['train']} training, {summary['objects_by_split']['heldout']} held out)"],
            ["grasps tried", grasps],
            ["held grasps", f"{held} ({_percent(held, grasps)})"],
            ["distinct held grasps", summary["distinct_held"]],
            ["batches", len(summary["per_batch"])],
            ["CPU hours", f"{cpu_hours:.2f}"],
        ]),  # fmt: skip
        "",
        *_progress(summary),
        *_distribution(summary),
        *_grasp_types(summary),
        *_batches(summary),
        "## Protocol",
        "",
        protocol_text.strip() or "_No protocol text was given._",
        "",
        *_layout(),
    ]
    return "\n".join(lines)


def write_card(dataset_dir: str | os.PathLike, protocol_text: str) -> Path:
    """Regenerate ``DATASET/CARD.md`` from the dataset's tables and grasps, with ``protocol_text``; returns its path."""
    path = Path(dataset_dir) / CARD_NAME
    write_text_atomic(path, card_text(dataset_dir, protocol_text))
    return path
