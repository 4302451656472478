"""Grasps that hold for the user's own meshes, in one call: ``dexlite grasp MESH [MESH ...] --out DIR``.

Steps (each logs its progress):

0. check everything before any work: options, config, device, model file, every mesh file
   (readable, a size plausible for a hand-held object in the given ``units``) and the output
   folder; any problem is one ``GraspToolError`` and nothing is written;
1. prepare every mesh that fits the Shadow Hand (repair, normalization, convex pieces, SDF)
   into ``DIR/objects``; one too large or too small for the hand, or that cannot be prepared,
   is listed with its reason and the others go on;
2. synthesize ``n`` grasps per object, **at the object's real size** (the mesh's own size in
   ``units``), or with ``resize_to_training`` at the training scales (object radius 8-12 cm):
   with a trained model (``cvae.pt``), CVAE samples refined by post-optimization (config
   sections ``sample`` and ``post_optimize``); without one, energy optimization from scratch
   (section ``optimize_grasps``, the pipeline's optimization from scratch);
3. lift test and six-direction test of every grasp with the ``lift`` section's constants
   (the pipeline's physics, unchanged);
4. with a model and ``min_distinct`` > 0, the top-up: each object whose grasps so far give
   fewer than ``min_distinct`` distinct held grasps gets a batch of ``n`` grasps by optimization
   from scratch (the same function and lift test as without a model; the first batch has the
   seeds of ``--from-scratch``), batch after batch until it has ``min_distinct`` or
   ``top_up_batches`` batches were tried; every grasp records its ``source`` (``model`` or
   ``optimization``);
5. distinct grasps among those held (``evaluation.diversity``, section ``diversity``) over
   both sources together, the better grasps first; with ``distinct`` only one of each
   near-duplicate is kept;
6. write ``DIR/grasps.zarr`` (the kept held grasps, same schema as the pipeline's stores),
   ``DIR/all_grasps.zarr`` (every grasp with its failure reason and distinct-grasp label),
   ``DIR/dexgraspnet/`` (DexGraspNet layout of the kept grasps and meshes, when any held),
   ``DIR/renders/*.png`` (different grasps), ``DIR/view.html`` (the kept grasps in an offline,
   turnable 3-D view) and ``DIR/summary.md``.

Settings are the package's default ``config.yaml`` overlaid by the caller's sections, read as
the typed tree (``settings.build_config``); the physics constants of the lift test are never
changed here. Sizes: the store's ``scale`` is the unit (metres) per file unit divided by the
asset's ``normalization_factor``, so the README's object-frame rule (p / scale /
normalization_factor + normalization_centre) gives back the mesh file's coordinates.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import shutil
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexlite_pipeline.sharding import shard_generator

log = logging.getLogger("dexlite.grasp")

DEFAULT_GRASPS_PER_OBJECT = 32
DEFAULT_RENDERS_PER_OBJECT = 2
STEPS = 5  # progress steps of a run without the top-up (one more with it)
UNIT_METRES = {"mm": 0.001, "cm": 0.01, "m": 1.0}
UNIT_NAMES = {"mm": "millimetres", "cm": "centimetres", "m": "metres"}
# A largest extent outside this range is a unit mistake (a 95 m mug is a mug in millimetres), not an object for a hand.
PLAUSIBLE_LARGEST_EXTENT_M = (0.01, 1.0)
# What the Shadow Hand can hold (heuristic limits from its geometry): the thumb and finger distal links open at
# most about 17-20 cm apart over the joint limits, less room to close, so an object whose thinnest side
# (oriented bounding box) is wider than 15 cm has no part the hand can close around; the distal links are
# 1.4 cm thick, so an object under 3 cm in every direction leaves no room for three of them to oppose each other.
HAND_MAX_THINNEST_EXTENT_M = 0.15
HAND_MIN_LARGEST_EXTENT_M = 0.03
# The summary suggests what to try for an object with fewer distinct held grasps than this.
WANTED_DISTINCT = 4
# Default --min-distinct: with a model, an object with fewer distinct held model grasps than this also gets grasps
# by optimization from scratch. The same number as the summary's hints, so the tool does by itself what the summary
# would otherwise tell the user to try; a handful of different grasps (palms 2 cm or 30 degrees apart) lets a robot
# pick one whose approach is free of the table, neighbouring objects and its arm's reach limits.
DEFAULT_MIN_DISTINCT = WANTED_DISTINCT
# Default cap of the top-up: at most this many batches of n optimization attempts per object. Optimization holds 5-45%
# of its attempts on household meshes and nearly every held grasp is distinct, so 4 batches of 32 reach 4 distinct
# grasps on all but the hardest shapes, and an object the hand cannot hold costs at most 4 optimizations.
DEFAULT_TOP_UP_BATCHES = 4
# The ``source`` array of the stores: which synthesis made each grasp.
SOURCE_MODEL = "model"
SOURCE_OPTIMIZATION = "optimization"
# A missing array of one source is filled for the other source's rows with this value, by dtype kind.
NOT_MADE = {"f": np.nan, "i": -1, "u": 0, "b": False, "O": ""}
# What dexlite grasp writes in its output folder: a folder holding one of these is an earlier run's output.
OUTPUT_MARKERS = ("summary.md", "all_grasps.zarr", "grasps.zarr", "objects")


class GraspToolError(ValueError):
    """Input the tool cannot work with (bad option, device, model file, mesh file or output folder)."""


@dataclass
class GraspRequest:
    """What to grasp and how: mesh files or folders, output folder, budget and options."""

    meshes: list[str]
    out_dir: str
    grasps_per_object: int = DEFAULT_GRASPS_PER_OBJECT
    units: str = "m"  # the mesh files' length unit: mm, cm or m
    resize_to_training: bool = False  # grasp each object resized to the training scales instead of its real size
    distinct: bool = True  # keep one grasp of each near-duplicate group in grasps.zarr
    overwrite: bool = False  # clear an earlier run's output folder first
    device: str | None = None  # None: the config's device
    model: str | None = None  # trained cvae.pt: sample + post-optimize; None: optimization from scratch
    # with a model: objects with fewer distinct held model grasps also get optimization from scratch (0: never)
    min_distinct: int = DEFAULT_MIN_DISTINCT
    top_up_batches: int = DEFAULT_TOP_UP_BATCHES  # at most this many top-up batches of n attempts per object
    config: dict = field(default_factory=dict)  # config sections over the defaults
    threads: int = 1
    renders_per_object: int = DEFAULT_RENDERS_PER_OBJECT
    upright_axis: str | None = None  # tabletop mode: the mesh axis pointing up (None: the mesh's stable pose)


@dataclass
class GraspOutcome:
    """Counts per object and where the outputs are."""

    objects: list[dict]
    rejected: list[dict]
    held: int
    distinct: int
    total: int
    seconds: float
    summary_path: Path
    next_steps: list[str] = field(default_factory=list)  # what to try next (the summary's list)
    topped_up: list[str] = field(default_factory=list)  # objects that optimization from scratch topped up


@dataclass(frozen=True)
class MeshSize:
    """A mesh file's size: its largest axis-aligned extent and its oriented-box extents (metres, thinnest first)."""

    largest_m: float
    oriented_m: tuple[float, float, float]


def tool_config(overlay: dict):
    """The typed config of a run: the package's default config.yaml with ``overlay``'s sections over it.

    Returns (typed tree, the merged mapping recorded in the outputs). Only the given meshes are objects.
    """
    from dexlite_pipeline.config import default_config, merge_config, validate_config
    from dexlite_pipeline.settings import build_config

    mapping = merge_config(default_config(), overlay)
    mapping["objects"] = {**mapping.get("objects", {}), "builtin_count": 0, "mesh_dirs": [], "heldout_mesh_dirs": []}
    validate_config(mapping, "configuration")
    return build_config(mapping, "configuration"), mapping


def mesh_sources(paths: list[str]):
    """One ``MeshSource`` per mesh file given, or per .obj/.stl file directly inside a folder given."""
    from dexlite_pipeline.objects.sources import MESH_SUFFIXES, make_ids_unique, user_mesh_sources

    files: list[Path] = []
    for text in paths:
        path = Path(text)
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in MESH_SUFFIXES)
            if not found:
                raise GraspToolError(f"{text}: folder has no {'/'.join(MESH_SUFFIXES)} files")
            files += found
        elif path.is_file():
            if path.suffix.lower() not in MESH_SUFFIXES:
                raise GraspToolError(f"{text}: not a mesh file (expected {' or '.join(MESH_SUFFIXES)})")
            files.append(path)
        else:
            raise GraspToolError(f"{text}: no such file or folder")
    unique = list(dict.fromkeys(p.resolve() for p in files))
    return make_ids_unique(user_mesh_sources(unique))


def _cm(metres: float) -> str:
    return f"{100 * metres:.3g} cm"


def _size_text(size: MeshSize) -> str:
    """'9.5 x 8 x 10 cm' from the oriented extents."""
    return " x ".join(f"{100 * e:.3g}" for e in size.oriented_m) + " cm"


def likely_unit(largest_in_file_units: float) -> str | None:
    """The unit that makes a mesh of this largest extent (in its file's units) most like a hand-held object."""
    typical = 0.15  # m: the middle of what a hand holds, on a log scale
    fits = [(abs(math.log(largest_in_file_units * m / typical)), u) for u, m in UNIT_METRES.items()
            if PLAUSIBLE_LARGEST_EXTENT_M[0] <= largest_in_file_units * m <= PLAUSIBLE_LARGEST_EXTENT_M[1]]  # fmt: skip
    return min(fits)[1] if fits else None


def measure_mesh(source, unit_m: float) -> MeshSize:
    """Read a mesh file (as preparation will) and measure it; an unreadable file is a ``GraspToolError``."""
    from dexlite_pipeline.objects.prepare import MeshRejected, load_source_mesh

    try:
        mesh = load_source_mesh(source)
    except MeshRejected as exc:
        raise GraspToolError(f"{source.file}: {exc}") from None
    largest = float(np.asarray(mesh.extents).max()) * unit_m
    try:
        oriented = sorted(float(e) * unit_m for e in mesh.bounding_box_oriented.primitive.extents)
    except Exception:  # noqa: BLE001 - a flat or odd mesh: its axis-aligned box stands in (preparation judges the shape)
        oriented = sorted(float(e) * unit_m for e in mesh.extents)
    return MeshSize(largest, tuple(oriented))


def implausible_size(file: str, size: MeshSize, units: str) -> str | None:
    """The refusal for a mesh too large or too small to be a hand-held object in ``units``, else None."""
    low, high = PLAUSIBLE_LARGEST_EXTENT_M
    if low <= size.largest_m <= high:
        return None
    in_file_units = size.largest_m / UNIT_METRES[units]
    unit = likely_unit(in_file_units)
    hint = f"likely in {unit} (--units {unit}: {_cm(in_file_units * UNIT_METRES[unit])})" if unit else "no unit makes it a hand-held object"
    in_metres = f" ({size.largest_m:g} m)" if units != "m" else ""
    return (f"{file}: largest extent {in_file_units:g} {units}{in_metres}, implausible for a hand-held object "
            f"({_cm(low)} to {high:g} m); {hint}")  # fmt: skip


def hand_fit_problem(size: MeshSize) -> str | None:
    """Why the Shadow Hand cannot hold an object of this size, or None when it may."""
    if size.oriented_m[0] > HAND_MAX_THINNEST_EXTENT_M:
        return (f"too large for the Shadow Hand: its thinnest side is {_cm(size.oriented_m[0])} "
                f"(the hand closes around at most {_cm(HAND_MAX_THINNEST_EXTENT_M)})")  # fmt: skip
    if size.largest_m < HAND_MIN_LARGEST_EXTENT_M:
        return f"too small for the Shadow Hand: {_cm(size.largest_m)} at most (it needs {_cm(HAND_MIN_LARGEST_EXTENT_M)})"
    return None


def output_folder_problem(out_dir: Path, overwrite: bool, mesh_files: list[str]) -> str | None:
    """Why ``out_dir`` cannot take this run's outputs, or None (absent, empty, or an earlier run's to clear)."""
    if out_dir.exists() and not out_dir.is_dir():
        return f"--out {out_dir}: exists and is not a folder"
    if not out_dir.is_dir() or not any(out_dir.iterdir()):
        return None
    if not any((out_dir / name).exists() for name in OUTPUT_MARKERS):
        return f"--out {out_dir}: folder is not empty and holds no earlier dexlite grasp output; choose an empty or new folder"
    if not overwrite:
        return f"--out {out_dir}: holds an earlier run's output; pass --overwrite to replace it, or choose a new folder"
    root = out_dir.resolve()
    inside = [f for f in mesh_files if root in Path(f).resolve().parents]
    if inside:
        return f"--out {out_dir}: --overwrite would delete the input mesh {inside[0]}; move it out first"
    return None


def check_device(name: str, where: str = "--device"):
    """The torch device for ``name`` (given as ``where``), or a ``GraspToolError`` naming what is wrong."""
    from dexlite_pipeline.device import resolve_device

    try:
        return resolve_device(name)
    except RuntimeError as exc:
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "CUDA is not available" in text:
            return _raise(f"{where} {name}: CUDA is not available on this machine; use --device cpu")
        return _raise(f"{where} {name}: not a device (expected auto, cpu, cuda or cuda:N)")


def _raise(message: str):
    raise GraspToolError(message)


def load_model(path: str, device):
    """The model and checkpoint entries of ``path``, or a one-line ``GraspToolError``."""
    from dexlite_pipeline.model.checkpoint import load_checkpoint

    file = Path(path)
    if not file.is_file():
        raise GraspToolError(f"--model {path}: no such file")
    try:
        return load_checkpoint(file, device)
    except Exception as exc:  # noqa: BLE001 - torch and the checkpoint reader raise many types for a bad file
        cause = exc.__cause__ or exc
        text = str(cause).splitlines()[0] if str(cause) else ""
        detail = text if text and len(text) <= 100 else type(cause).__name__  # torch's messages run to many lines
        raise GraspToolError(f"--model {path}: not a readable model file ({detail})") from None


def _step(number: int, steps: int, text: str, *args) -> None:
    log.info(f"[{number}/{steps}] {text}", *args)


def object_scales(assets, request: GraspRequest, configured: tuple[float, ...]) -> dict[str, tuple[float, ...]]:
    """Scales per object: the real size (file unit in metres / normalization factor), or the configured ones."""
    if request.resize_to_training:
        return {a.object_id: tuple(configured) for a in assets}
    unit_m = UNIT_METRES[request.units]
    scales = {}
    for asset in assets:
        factor = float(asset.meta.get("normalization_factor", math.nan))
        if not math.isfinite(factor) or factor <= 0:
            raise GraspToolError(f"{asset.object_id}: asset has no normalization factor; cannot keep its real size")
        scales[asset.object_id] = (unit_m / factor,)
    return scales


def _balanced_rows(per_scale: int, scale_count: int, wanted: int) -> np.ndarray:
    """Rows of a scale-major block (``per_scale`` grasps per scale) taking ``wanted``, the scales in turn."""
    k = np.arange(per_scale * scale_count)
    order = np.lexsort((k // per_scale, k % per_scale))
    return np.sort(order[:wanted])


def synthesize_from_scratch(assets, scales: dict, n: int, config, device, seed: int, support_planes=None):
    """``n`` grasps per object by energy optimization from convex-hull starts (section ``optimize_grasps``)."""
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.optim.from_scratch import synthesize

    generator = shard_generator("optimize_grasps", seed, 0)
    parts = []
    for number, asset in enumerate(assets, start=1):
        object_scales = scales[asset.object_id]
        per_scale = -(-n // len(object_scales))
        optimize_config = dataclasses.replace(config.optimize_grasps, grasps_per_object=per_scale, scales=object_scales)
        log.info("object %d/%d %s: optimizing %d grasps, %d iterations", number, len(assets), asset.object_id,
                 per_scale * len(object_scales), optimize_config.annealing.iterations)
        grasps, _ = synthesize([asset], optimize_config, config.energy, generator, device, support_planes=support_planes)
        parts.append(grasps.select(_balanced_rows(per_scale, len(object_scales), n)))
    grasps = GraspSet.concatenate(parts)
    grasps.arrays["method"] = np.full(len(grasps), "optimization", dtype=object)
    return grasps


def synthesize_with_model(assets, scales: dict, n: int, config, loaded, model_path: str, device, seed: int, support_planes=None):
    """``n`` CVAE samples per object, refined by post-optimization (sections ``sample``, ``post_optimize``)."""
    import torch

    from dexlite_pipeline.energy.config import EnergyConfig
    from dexlite_pipeline.energy.grasp_energy import GraspEnergy, max_scale_by_object
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.model.checkpoint import cloud_reading
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.optim.post import refine
    from dexlite_pipeline.model.sampling import synthesize

    sample_config, post_config = config.sample, config.post_optimize
    model, checkpoint = loaded
    points, fixed = cloud_reading(checkpoint, sample_config.points_per_cloud)
    clouds = ObjectClouds(assets, device)
    object_index = np.repeat(np.arange(len(assets)), n)
    scale = np.concatenate([np.resize(np.asarray(scales[a.object_id], np.float32), n) for a in assets])
    trained = sorted(float(s) for s in sample_config.scales)  # the training grasps' scales
    outside = sorted({round(float(s), 4) for s in scale if not min(trained) * 0.8 <= s <= max(trained) * 1.25})
    if outside:
        log.info("object radii %s m are outside the model's training radii %s m: expect fewer grasps that hold", outside, trained)
    generator = shard_generator("grasp_tool_post_optimize", seed, 0)
    log.info("sampling %d grasps from %s", len(object_index), model_path)
    prior, anchor_rule = sample_config.latent_prior, sample_config.anchor_rule
    if len(model.codes_mu) == 0 or len(model.codes_condition) == 0:  # a model saved without its training codes
        log.warning("%s holds no training codes: sampling from N(0, I) at uniform points instead of %s / %s", model_path, prior, anchor_rule)
        prior, anchor_rule = "standard", "uniform"
    poses = synthesize(
        model, clouds, object_index, scale, points, generator, prior, sample_config.latent_temperature, fixed, anchor_rule,
        sample_config.neighbour_clouds, sample_config.anchor_region_m, sample_config.debias_training, sample_config.match_candidates,
        sample_config.debias_codes,
    )
    if support_planes is not None:  # tabletop: samples whose hand starts below the table are raised above it first
        from dexlite_pipeline.energy.table_clearance import raise_above_table

        starts = GraspSet({"hand_pose": poses.detach().cpu().numpy(), "object_id": np.asarray([assets[i].object_id for i in object_index], dtype=object),
                           "scale": scale})  # fmt: skip
        poses = torch.as_tensor(raise_above_table(starts, support_planes)[0].hand_pose, dtype=poses.dtype, device=poses.device)
    hand = ShadowHand(device)
    energy = GraspEnergy.from_assets(
        hand, assets,
        EnergyConfig(weights=post_config.energy_weights, object_point_spacing_m=post_config.energy_point_spacing_m,
                     self_penetration_margin_m=config.energy.self_penetration_margin_m),
        support_planes=support_planes,
        max_scale=max_scale_by_object([assets[i].object_id for i in object_index], scale),
    )  # fmt: skip
    log.info("post-optimizing %d grasps, %d iterations", len(object_index), post_config.annealing.iterations)
    refined = refine(
        energy, poses, torch.as_tensor(object_index, device=device), torch.as_tensor(scale, device=device), post_config, generator, "surface"
    )
    arrays = {k: v for k, v in refined.arrays.items() if not k.startswith("trace_") and k != "energy_trace"}
    arrays["object_id"] = np.asarray([assets[i].object_id for i in object_index], dtype=object)
    arrays["scale"] = scale
    arrays["method"] = np.full(len(object_index), "cvae_post", dtype=object)
    return GraspSet(arrays)


def grasp_rank(grasps) -> np.ndarray:
    """Row order best first: held, six-direction passed, more of the six directions passed, lower energy."""
    arrays = grasps.arrays
    n = len(grasps)
    held = np.asarray(arrays.get("lift_success", np.zeros(n, bool)), bool)
    six = np.asarray(arrays.get("six_dir_success", np.zeros(n, bool)), bool)
    passed = np.asarray(arrays["six_dir_passed"], bool).reshape(n, -1).sum(axis=1) if "six_dir_passed" in arrays else np.zeros(n)
    energy = np.full(n, np.inf)
    for name in ("E_total", "E_post"):  # a model grasp's post-optimization energy, else the optimizer's (rows of both sources)
        if name in arrays:
            values = np.asarray(arrays[name], np.float64)
            energy = np.where(np.isfinite(values), values, energy)
    return np.lexsort((np.arange(n), energy, -passed, ~six, ~held))


def distinct_labels(grasps, config) -> np.ndarray:
    """(N,) distinct-grasp label of each held grasp (clusters of one object and scale, best grasp first), -1 if not held."""
    from dexlite_pipeline.evaluation.diversity import distinct_grasp_labels

    held = np.asarray(grasps.arrays["lift_success"], bool)
    labels = np.full(len(grasps), -1, dtype=np.int64)
    order = [i for i in grasp_rank(grasps) if held[i]]
    if order:
        groups = np.asarray([f"{grasps.object_id[i]}@{float(grasps.scale[i]):.6g}" for i in order])
        labels[order] = distinct_grasp_labels(
            grasps.hand_pose[order], groups, config.diversity.distinct_translation_m, config.diversity.distinct_rotation_deg
        )
    return labels


def representatives(grasps, labels: np.ndarray) -> np.ndarray:
    """Rows of the best grasp of each distinct-grasp cluster, best first (clusters are numbered best first)."""
    order = [i for i in grasp_rank(grasps) if labels[i] >= 0]
    seen: set[int] = set()
    rows = []
    for i in order:
        if labels[i] not in seen:
            seen.add(int(labels[i]))
            rows.append(i)
    return np.asarray(rows, dtype=np.int64)


def distinct_per_object(grasps, labels: np.ndarray) -> Counter:
    """Object id -> number of distinct held grasps (labels from ``distinct_labels``; objects with none are absent)."""
    held = labels >= 0
    return Counter(str(o) for o, _ in set(zip(grasps.object_id[held].tolist(), labels[held].tolist())))


def objects_to_top_up(assets, grasps, labels: np.ndarray, min_distinct: int) -> list:
    """The assets whose grasps so far give fewer than ``min_distinct`` distinct held grasps (none when it is 0)."""
    counts = distinct_per_object(grasps, labels)
    return [a for a in assets if counts[a.object_id] < min_distinct]


def top_up_until_distinct(assets, tested, config, min_distinct: int, max_batches: int, optimized_batch):
    """Add batches of optimization from scratch to the objects with fewer than ``min_distinct`` distinct held grasps.

    ``optimized_batch(chosen_assets, batch)`` makes and tests batch ``batch`` (0-based) for the chosen objects; after
    each batch the objects are counted again over every grasp so far (all sources together) and only those still
    short get the next one, for at most ``max_batches`` batches. Returns the grasps with the batches appended, the
    object ids that got at least one batch, and the assets still short after the last batch."""
    short = objects_to_top_up(assets, tested, distinct_labels(tested, config), min_distinct)
    topped_up: list[str] = []
    for batch in range(max_batches):
        if not short:
            break
        if batch:
            log.info("top-up batch %d/%d: still fewer than %d distinct held grasps for %d object(s) (%s)", batch + 1, max_batches,
                     min_distinct, len(short), ", ".join(a.object_id for a in short))  # fmt: skip
        topped_up += [a.object_id for a in short if a.object_id not in topped_up]
        tested = concatenate_sources([tested, optimized_batch(short, batch)])
        short = objects_to_top_up(short, tested, distinct_labels(tested, config), min_distinct)
    return tested, topped_up, short


def top_up_seed(seed: int, batch: int) -> int:
    """The random seed of top-up batch ``batch`` (0-based): batch 0 has ``seed`` itself, so its grasps are those of
    ``--from-scratch``; later batches get independent streams derived from (seed, batch)."""
    return seed if batch == 0 else int(np.random.SeedSequence([seed, batch]).generate_state(1)[0])


def concatenate_sources(parts: list):
    """The grasp sets of both sources as one; an array only one source has is filled for the other's rows (``NOT_MADE``)."""
    from dexlite_pipeline.io.grasp_store import GraspSet

    names = list(dict.fromkeys(k for part in parts for k in part.arrays))
    examples = {k: next(part.arrays[k] for part in parts if k in part.arrays) for k in names}
    arrays = {
        k: np.concatenate([
            part.arrays[k] if k in part.arrays
            else np.full((len(part), *examples[k].shape[1:]), NOT_MADE[examples[k].dtype.kind], dtype=examples[k].dtype)
            for part in parts
        ])
        for k in names
    }  # fmt: skip
    return GraspSet(arrays, dict(parts[0].attrs))


def per_source_counts(grasps, config) -> dict[str, dict[str, dict[str, int]]]:
    """Object id -> source -> attempts, held and distinct held grasps among that source's grasps alone."""
    sources = np.asarray(grasps.arrays["source"], dtype=object)
    held = np.asarray(grasps.arrays["lift_success"], bool)
    counts: dict[str, dict[str, dict[str, int]]] = {}
    for source in dict.fromkeys(sources.tolist()):
        part = grasps.select(np.flatnonzero(sources == source))
        distinct = distinct_per_object(part, distinct_labels(part, config))
        for object_id in dict.fromkeys(part.object_id.tolist()):
            mask = (grasps.object_id == object_id) & (sources == source)
            counts.setdefault(object_id, {})[source] = {"grasps": int(mask.sum()), "held": int(held[mask].sum()), "distinct": distinct[object_id]}
    return counts


def render_examples(grasps, labels: np.ndarray, objects_dir: Path, out_dir: Path, per_object: int) -> list[Path]:
    """Up to ``per_object`` different held grasps per object as PNGs, the best first (one failure when none held)."""
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.report.render import grasp_table, render_grasp_png

    hand, written = ShadowHand(), []
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
            title = f"{object_id}  grasp {row}{source}  object radius {100 * float(grasps.scale[row]):.3g} cm\n{outcome}"
            render_grasp_png(hand, grasps.hand_pose[row], object_id, float(grasps.scale[row]), [str(objects_dir)], out=path, title=title,
                             table=grasp_table(grasps, row))
            written.append(path)
    return written


def failure_counts(reasons) -> dict[str, int]:
    """Failure reasons of grasps that did not hold, most frequent first ('initial_penetration' -> 'initial penetration')."""
    counts = Counter(str(r).replace("_", " ") if r else "dropped" for r in reasons)
    return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def per_object_rows(grasps, labels: np.ndarray, sources, sizes: dict, prepared_ids: list[str], coverage: dict | None = None) -> list[dict]:
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


def _depth(mm: float) -> str:
    return "-" if mm != mm else f"{mm:.1f}"


def _percent(share: float) -> str:
    return "-" if share != share else f"{100 * share:.0f}%"


def _share(count: int, total: int) -> str:
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
        scratch = (_share(optimized["held"], optimized["grasps"]), optimized["distinct"]) if optimized else ("not run", "-")
        lines.append(f"| {r['object_id']} | {_share(model['held'], model['grasps'])} | {model['distinct']} | {scratch[0]} | {scratch[1]} | {r['distinct']} |")
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


def summary_markdown(
    request: GraspRequest, rows: list[dict], rejected: list[dict], method: str, step_seconds: dict, renders: list[Path], lift_config, diversity, kept: int,
    view: Path | None = None,
) -> str:
    """The one-page ``summary.md``: per object its size, held and distinct counts, failure reasons; what to try next."""
    total = sum(r["grasps"] for r in rows)
    lift, six, both, distinct = (sum(r[k] for r in rows) for k in ("lift", "six_dir", "both", "distinct"))
    seconds = sum(step_seconds.values())
    size_rule = ("each object resized to the training radii" if request.resize_to_training
                 else f"each object at its real size (mesh units: {request.units})")  # fmt: skip
    lines = [
        "# Grasps",
        "",
        f"**{_share(lift, total)} grasps held the object in the lift test, {distinct} of them distinct; {_share(both, total)} also "
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
        lines.append(f"| {r['object_id']} | {Path(r['file']).name} | {size} | {r['grasps']} | {_share(r['lift'], r['grasps'])} | "
                     f"{r['distinct']} | {_depth(r.get('start_depth_max_mm', math.nan))} | {_percent(r.get('coverage', math.nan))} | "
                     f"{_share(r['six_dir'], r['grasps'])} | {_share(r['both'], r['grasps'])} | {reasons} |")
    lines.append(f"| **all** | | | {total} | {_share(lift, total)} | {distinct} | | | {_share(six, total)} | {_share(both, total)} | |")
    lines += source_lines(request, rows)
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


@dataclass
class CheckedRequest:
    """Everything a run needs, checked before any work."""

    config: object  # settings.PipelineConfig
    mapping: dict
    device: object
    loaded_model: tuple | None
    sources: list
    sizes: dict  # object id -> MeshSize
    not_tried: list[dict]  # meshes the hand cannot hold: file, reason, kind


def check_request(request: GraspRequest) -> CheckedRequest:
    """Every check that can fail on the user's input, before anything is prepared or written."""
    if request.grasps_per_object < 1:
        raise GraspToolError(f"--n must be at least 1, got {request.grasps_per_object}")
    if request.renders_per_object < 0:
        raise GraspToolError(f"--renders must be 0 or more, got {request.renders_per_object}")
    if request.min_distinct < 0:
        raise GraspToolError(f"--min-distinct must be 0 or more, got {request.min_distinct}")
    if request.top_up_batches < 1:
        raise GraspToolError(f"--top-up-batches must be at least 1, got {request.top_up_batches}")
    if request.threads < 1:
        raise GraspToolError(f"--threads must be at least 1, got {request.threads}")
    if request.units not in UNIT_METRES:
        raise GraspToolError(f"--units {request.units}: expected one of {', '.join(UNIT_METRES)}")
    config, mapping = tool_config(request.config)
    out_dir = Path(request.out_dir)
    sources = mesh_sources(request.meshes)
    problem = output_folder_problem(out_dir, request.overwrite, [s.file for s in sources])
    if problem:
        raise GraspToolError(problem)
    device = check_device(request.device, "--device") if request.device else check_device(config.device, "config device")
    loaded = load_model(request.model, device) if request.model else None
    sizes, not_tried, refusals = {}, [], []
    for source in sources:
        size = measure_mesh(source, UNIT_METRES[request.units])
        sizes[source.object_id] = size
        if request.resize_to_training:
            continue
        refusal = implausible_size(source.file, size, request.units)
        if refusal:
            refusals.append(refusal)
            continue
        fit = hand_fit_problem(size)
        if fit:
            not_tried.append({"file": source.file, "reason": fit, "kind": "hand_fit"})
    if refusals:
        raise GraspToolError(refusals[0] + (f" (and {len(refusals) - 1} more mesh(es) like it)" if len(refusals) > 1 else ""))
    if len(not_tried) == len(sources):
        raise GraspToolError("; ".join(f"{r['file']}: {r['reason']}" for r in not_tried)
                             + f" (if a file is not in {UNIT_NAMES[request.units]}, give its unit with --units)")
    return CheckedRequest(config, mapping, device, loaded, sources, sizes, not_tried)


def run_grasp_tool(request: GraspRequest) -> GraspOutcome:
    """Check, prepare, synthesize, test and write everything for ``request`` (see the module docstring)."""
    from dexlite_pipeline.atomic import write_text_atomic
    from dexlite_pipeline.evaluation.metrics import per_object_diversity
    from dexlite_pipeline.evaluation.protocol import coverage_arrays
    from dexlite_pipeline.io.dexgraspnet import export_dexgraspnet
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.objects.prepare import prepare_objects
    from dexlite_pipeline.report.grasp_view import write_grasp_set_view
    from dexlite_pipeline.sim.results import lift_grasp_set
    from dexlite_pipeline.tabletop import tool_support_planes

    checked = check_request(request)
    config = checked.config
    started = time.perf_counter()
    out_dir = Path(request.out_dir)
    if request.overwrite and out_dir.is_dir() and any(out_dir.iterdir()):
        log.info("--overwrite: clearing the earlier run's output in %s", out_dir)
        shutil.rmtree(out_dir)
    objects_dir = out_dir / "objects"
    skipped = {r["file"] for r in checked.not_tried}
    sources = [s for s in checked.sources if s.file not in skipped]
    for r in checked.not_tried:
        log.warning("not tried: %s: %s", r["file"], r["reason"])
    times: dict[str, float] = {}

    top_up = bool(request.model) and request.min_distinct > 0
    steps = STEPS + top_up
    _step(1, steps, "preparing %d mesh(es) into %s", len(sources), objects_dir)
    t = time.perf_counter()
    catalog = prepare_objects(sources, objects_dir, config.objects, config.seed, request.threads)
    times["prepare"] = time.perf_counter() - t
    failed = [{"file": r.file, "reason": r.reason, "kind": "prepare"} for r in catalog[catalog["status"] != "ok"].itertuples()]
    ok_ids = sorted(catalog.loc[catalog["status"] == "ok", "object_id"])
    rejected = checked.not_tried + failed
    if not ok_ids:
        raise GraspToolError(f"none of the {len(checked.sources)} mesh(es) could be used: " + "; ".join(f"{r['file']}: {r['reason']}" for r in rejected))
    for r in failed:
        log.warning("mesh not usable: %s: %s", r["file"], r["reason"])
    log.info("prepared %d of %d mesh(es)", len(ok_ids), len(checked.sources))
    assets = [load_asset(objects_dir, oid) for oid in ok_ids]
    # tabletop: each object's table (None: floating)
    planes, support = tool_support_planes(assets, config.scene.table, request.upright_axis, config.stability, config.seed)
    lift_config = dataclasses.replace(config.lift, six_directions=True)

    def optimized(chosen, times_key: str, seed: int):
        """``n`` grasps per chosen object by optimization from scratch: ``--from-scratch`` and the top-up alike."""
        t = time.perf_counter()
        grasps = synthesize_from_scratch(chosen, object_scales(chosen, request, config.optimize_grasps.scales), request.grasps_per_object, config,
                                         checked.device, seed, planes)  # fmt: skip
        times[times_key] = times.get(times_key, 0.0) + time.perf_counter() - t
        return grasps

    def lift_tested(grasps, source: str, times_key: str):
        """The grasps with their lift and six-direction test results and their ``source``."""
        t = time.perf_counter()
        tested, _ = lift_grasp_set(grasps, [str(objects_dir)], lift_config, request.threads, support_planes=planes)
        tested.arrays["source"] = np.full(len(tested), source, dtype=object)
        times[times_key] = times.get(times_key, 0.0) + time.perf_counter() - t
        return tested

    testing = "lift test and six-direction test of %d grasps on %d thread(s)"
    if request.model:
        method = f"CVAE samples + post-optimization ({request.model})"
        _step(2, steps, "synthesizing %d grasps for each of %d object(s): %s, device %s", request.grasps_per_object, len(assets), method, checked.device)
        t = time.perf_counter()
        grasps = synthesize_with_model(assets, object_scales(assets, request, config.sample.scales), request.grasps_per_object, config,
                                       checked.loaded_model, request.model, checked.device, config.seed, planes)  # fmt: skip
        times["synthesize"] = time.perf_counter() - t
        _step(3, steps, testing, len(grasps), request.threads)
        tested = lift_tested(grasps, SOURCE_MODEL, "lift and six-direction tests")
    else:
        method = "energy optimization from scratch"
        _step(2, steps, "optimizing %d grasps for each of %d object(s) from scratch, device %s", request.grasps_per_object, len(assets), checked.device)
        grasps = optimized(assets, "synthesize", config.seed)
        _step(3, steps, testing, len(grasps), request.threads)
        tested = lift_tested(grasps, SOURCE_OPTIMIZATION, "lift and six-direction tests")
    topped_up: list[str] = []
    if top_up:
        short = objects_to_top_up(assets, tested, distinct_labels(tested, config), request.min_distinct)
        if short:
            _step(4, steps, "top-up: the model gave fewer than %d distinct held grasps (--min-distinct) for %d of %d object(s) (%s): "
                  "optimizing batches of %d grasps from scratch until each has %d (at most %d batches), device %s", request.min_distinct,
                  len(short), len(assets), ", ".join(a.object_id for a in short), request.grasps_per_object, request.min_distinct,
                  request.top_up_batches, checked.device)  # fmt: skip
        else:
            _step(4, steps, "no top-up: the model gave at least %d distinct held grasps (--min-distinct) for every object", request.min_distinct)

        def optimized_batch(chosen, batch: int):
            grasps = optimized(chosen, "top-up: synthesize", top_up_seed(config.seed, batch))
            log.info("top-up batch %d: " + testing, batch + 1, len(grasps), request.threads)
            return lift_tested(grasps, SOURCE_OPTIMIZATION, "top-up: lift and six-direction tests")

        tested, topped_up, short = top_up_until_distinct(assets, tested, config, request.min_distinct, request.top_up_batches, optimized_batch)
        if short:
            log.warning("top-up: after %d batch(es) still fewer than %d distinct held grasps for %s", request.top_up_batches,
                        request.min_distinct, ", ".join(a.object_id for a in short))  # fmt: skip
        if topped_up:
            method += f", topped up by energy optimization from scratch on {len(topped_up)} of {len(assets)} object(s)"
    done = 3 + top_up

    _step(done + 1, steps, "distinct grasps, grasp stores and the DexGraspNet export")
    t = time.perf_counter()
    labels = distinct_labels(tested, config)
    tested.arrays["distinct_label"] = labels
    held_mask = labels >= 0
    kept_rows = representatives(tested, labels) if request.distinct else np.flatnonzero(held_mask)
    kept = tested.select(np.sort(kept_rows))
    attrs = {
        "stage": "grasp", "method": method, "config": checked.mapping, "units": request.units,
        "size": "resized to the training scales" if request.resize_to_training else "real size",
        "meshes": [s.file for s in checked.sources], "support": support,
        "min_distinct": request.min_distinct if request.model else None, "topped_up": topped_up,
    }  # fmt: skip
    write_grasp_store(out_dir / "all_grasps.zarr", tested, attrs)
    selection = "lift_success, one per distinct_label (the best)" if request.distinct else "lift_success"
    write_grasp_store(out_dir / "grasps.zarr", kept, {**attrs, "selection": selection})
    if len(kept):
        export_dexgraspnet(kept, out_dir / "dexgraspnet", [str(objects_dir)])
    times["distinct grasps and writing"] = time.perf_counter() - t

    _step(done + 2, steps, "rendering examples and writing the summary")
    t = time.perf_counter()
    renders = render_examples(tested, labels, objects_dir, out_dir / "renders", request.renders_per_object) if request.renders_per_object > 0 else []
    times["render"] = time.perf_counter() - t
    t = time.perf_counter()
    view = write_grasp_set_view(out_dir / "view.html", kept, [str(objects_dir)], title=method) if len(kept) else None
    times["3-D view"] = time.perf_counter() - t
    t = time.perf_counter()
    touched = coverage_arrays(tested, [str(objects_dir)], config.diversity)
    diversity_rows = per_object_diversity({**tested.arrays, **touched}, held_mask, config.diversity)
    times["surface coverage"] = time.perf_counter() - t
    coverage = {object_id: row["coverage"] for object_id, row in diversity_rows.items()}
    rows = per_object_rows(tested, labels, checked.sources, checked.sizes, ok_ids, coverage)
    by_source = per_source_counts(tested, config)
    for r in rows:
        r["by_source"], r["topped_up"] = by_source.get(r["object_id"], {}), r["object_id"] in topped_up
    summary_path = out_dir / "summary.md"
    write_text_atomic(summary_path, summary_markdown(request, rows, rejected, method, times, renders, lift_config, config.diversity, len(kept), view))
    seconds = time.perf_counter() - started
    for r in rows:
        reasons = ", ".join(f"{k} {v}" for k, v in r["failures"].items()) or "none"
        log.info("%s: held %s, %d distinct; failures: %s", r["object_id"], _share(r["lift"], r["grasps"]), r["distinct"], reasons)
    return GraspOutcome(objects=rows, rejected=rejected, held=int(held_mask.sum()), distinct=sum(r["distinct"] for r in rows),
                        total=len(tested), seconds=seconds, summary_path=summary_path, next_steps=next_steps(request, rows, rejected),
                        topped_up=topped_up)  # fmt: skip
