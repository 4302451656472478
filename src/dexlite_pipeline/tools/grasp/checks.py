"""Every check of a ``dexlite grasp`` request before any work: options, config, device, model file, every mesh
file (readable, a size plausible for a hand-held object in the given units, one the Shadow Hand can hold: the same
limits for every hand), the hand (config key ``hand``, ``--hand``) and the output folder. A problem that stops the run is one ``GraspToolError``; a mesh the hand cannot hold is only listed."""

from __future__ import annotations

import dataclasses

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dexlite_pipeline.tools.grasp.request import UNIT_METRES, UNIT_NAMES, GraspRequest, GraspToolError

if TYPE_CHECKING:
    import torch

    from dexlite_pipeline.objects.sources import MeshSource
    from dexlite_pipeline.settings import PipelineConfig

# A largest extent outside this range is a unit mistake (a 95 m mug is a mug in millimetres), not an object for a hand.
PLAUSIBLE_LARGEST_EXTENT_M = (0.01, 1.0)
# What the Shadow Hand can hold (heuristic limits from its geometry): the thumb and finger distal links open at
# most about 17-20 cm apart over the joint limits, less room to close, so an object whose thinnest side
# (oriented bounding box) is wider than 15 cm has no part the hand can close around; the distal links are
# 1.4 cm thick, so an object under 3 cm in every direction leaves no room for three of them to oppose each other.
HAND_MAX_THINNEST_EXTENT_M = 0.15
HAND_MIN_LARGEST_EXTENT_M = 0.03
# What dexlite grasp writes in its output folder: a folder holding one of these is an earlier run's output.
OUTPUT_MARKERS = ("summary.md", "all_grasps.zarr", "grasps.zarr", "objects")


@dataclass(frozen=True)
class MeshSize:
    """A mesh file's size: its largest axis-aligned extent and its oriented-box extents (metres, thinnest first)."""

    largest_m: float
    oriented_m: tuple[float, float, float]


@dataclass
class CheckedRequest:
    """Everything a run needs, checked before any work."""

    config: PipelineConfig
    mapping: dict  # the merged config mapping recorded in the outputs
    device: torch.device
    loaded_model: tuple | None  # (model, checkpoint entries) of ``--model``; None: optimization from scratch
    loaded_evaluator: tuple | None  # (evaluator, its meta) of ``--evaluator``; None: samples not ranked
    sources: list[MeshSource]
    sizes: dict[str, MeshSize]  # object id -> its mesh's size
    not_tried: list[dict]  # meshes the hand cannot hold: file, reason, kind
    hand: object = None  # the hand model (config key ``hand``, ``hand.choice.resolve_hand``) on ``device``
    hand_record: dict = dataclasses.field(default_factory=dict)  # what the stores record of it (``hand.choice.hand_record``)


def tool_config(overlay: dict) -> tuple[PipelineConfig, dict]:
    """The typed config of a run: the package's default config.yaml with ``overlay``'s sections over it.

    Returns (typed tree, the merged mapping recorded in the outputs). Only the given meshes are objects.
    """
    from dexlite_pipeline.config import default_config, merge_config, validate_config
    from dexlite_pipeline.settings import build_config

    mapping = merge_config(default_config(), overlay)
    mapping["objects"] = {**mapping.get("objects", {}), "builtin_count": 0, "mesh_dirs": [], "heldout_mesh_dirs": []}
    validate_config(mapping, "configuration")
    return build_config(mapping, "configuration"), mapping


def mesh_sources(paths: list[str]) -> list[MeshSource]:
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


def likely_unit(largest_in_file_units: float) -> str | None:
    """The unit that makes a mesh of this largest extent (in its file's units) most like a hand-held object."""
    typical = 0.15  # m: the middle of what a hand holds, on a log scale
    fits = [(abs(math.log(largest_in_file_units * m / typical)), u) for u, m in UNIT_METRES.items()
            if PLAUSIBLE_LARGEST_EXTENT_M[0] <= largest_in_file_units * m <= PLAUSIBLE_LARGEST_EXTENT_M[1]]  # fmt: skip
    return min(fits)[1] if fits else None


def measure_mesh(source: MeshSource, unit_m: float) -> MeshSize:
    """Read a mesh file (as preparation will) and measure it; an unreadable file is a ``GraspToolError``."""
    from dexlite_pipeline.objects.asset_building import MeshRejected, load_source_mesh

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


def check_device(name: str, where: str = "--device") -> torch.device:
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


def _load_file(option: str, path: str, loader, what: str) -> tuple:
    """``loader(path)``, or a one-line ``GraspToolError`` naming ``option`` and the file: missing, or not ``what``."""
    file = Path(path)
    if not file.is_file():
        raise GraspToolError(f"{option} {path}: no such file")
    try:
        return loader(file)
    except Exception as exc:  # noqa: BLE001 - torch and the file readers raise many types for a bad file
        cause = exc.__cause__ or exc
        text = str(cause).splitlines()[0] if str(cause) else ""
        detail = text if text and len(text) <= 100 else type(cause).__name__  # torch's messages run to many lines
        raise GraspToolError(f"{option} {path}: not a readable {what} ({detail})") from None


def load_model(path: str, device: torch.device, hand_record: dict | None = None) -> tuple:
    """The model and checkpoint entries of ``path``, or a one-line ``GraspToolError``: also for a model of another hand
    than ``hand_record`` (the run's, ``--hand``; None: any)."""
    from dexlite_pipeline.model.checkpoint import load_checkpoint
    from dexlite_pipeline.model.hand_match import hand_mismatch

    loaded = _load_file("--model", path, lambda file: load_checkpoint(file, device), "model file")
    if hand_record is not None and (problem := hand_mismatch(path, loaded[0].hand_record, hand_record)):
        raise GraspToolError(f"--model {problem}, or add --from-scratch (optimization from scratch takes any hand)")
    return loaded


def model_type_problem(path: str | None, loaded: tuple | None, grasp_type: str) -> str | None:
    """Why the loaded model at ``path`` cannot make ``grasp_type`` grasps (``--grasp-type``), naming the file; None when it can."""
    from dexlite_pipeline.model.type_condition import refusal

    reason = refusal(loaded[0].type_vocabulary, grasp_type) if loaded is not None else ""
    return f"--model {path}: {reason} (--grasp-type {grasp_type})" if reason else None


def load_grasp_evaluator(path: str, device: torch.device, hand_record: dict | None = None) -> tuple:
    """The grasp evaluator and its meta of ``path``, or a one-line ``GraspToolError``: also for an evaluator of another
    hand than ``hand_record`` (the run's; None: any)."""
    from dexlite_pipeline.model.evaluator import load_evaluator
    from dexlite_pipeline.model.hand_match import same_hand

    loaded = _load_file("--evaluator", path, lambda file: load_evaluator(file, device), "grasp evaluator file")
    if hand_record is not None and not same_hand(loaded[0].hand_record, hand_record):
        raise GraspToolError(f"--evaluator {path}: a grasp evaluator of hand {loaded[0].hand_record['hand']}, this run's hand is "
                             f"{hand_record['hand']}: give one trained for it, or --no-evaluator")
    return loaded


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
    if not request.resize_to_training:  # the file's unit is known: the prepared-versus-input check's millimetre floor
        sources = [dataclasses.replace(s, metres_per_unit=UNIT_METRES[request.units]) for s in sources]
    problem = output_folder_problem(out_dir, request.overwrite, [s.file for s in sources])
    if problem:
        raise GraspToolError(problem)
    device = check_device(request.device, "--device") if request.device else check_device(config.device, "config device")
    hand, record = check_hand_choice(config, request, device)
    if request.evaluator and not request.model:
        raise GraspToolError("--evaluator ranks a model's samples: it needs a model (not --from-scratch)")
    loaded = load_model(request.model, device, record) if request.model else None
    type_problem = model_type_problem(request.model, loaded, config.sample.grasp_type)
    if type_problem:
        raise GraspToolError(type_problem)
    evaluator = load_grasp_evaluator(request.evaluator, device, record) if request.evaluator else None
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
    return CheckedRequest(config, mapping, device, loaded, evaluator, sources, sizes, not_tried, hand, record)


def check_hand_choice(config: PipelineConfig, request: GraspRequest, device: torch.device) -> tuple[object, dict]:
    """The hand of config key ``hand`` (``--hand``) on ``device`` and its store record; ``GraspToolError`` in one
    line for a hand that cannot be made, and for grasp types the hand does not offer (``optim.grasp_types.hand_grasp_types``:
    a hand from its MJCF has the types its fingers allow). A model (``--model``; the shipped one is the Shadow Hand's) must
    be of the hand: ``load_model``."""
    from dexlite_pipeline.hand.choice import HandChoiceError, hand_record, resolve_hand
    from dexlite_pipeline.optim.grasp_types import check_hand_offers

    try:
        hand, record = resolve_hand(config.hand, device), hand_record(config.hand)
    except HandChoiceError as exc:
        raise GraspToolError(str(exc)) from None
    wanted = [name for name, share in config.optimize_grasps.grasp_types.shares().items() if share > 0]
    try:
        check_hand_offers(hand, wanted)
    except ValueError as exc:
        raise GraspToolError(f"hand: {config.hand}: {exc}") from None
    return hand, record
