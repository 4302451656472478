"""Grasps for meshes from Python: ``dexlite_pipeline.api.grasp(meshes, ...)``, what ``dexlite grasp`` does, as a function.

```python
from dexlite_pipeline.api import grasp

result = grasp(["mug.obj"], n=32, units="m", seed=0)
for mesh in result.meshes.values():
    print(mesh.name, mesh.held, "held of", mesh.attempts, "tried;", len(mesh.hand_pose), "distinct kept")
    palm = mesh.palm_in_mesh[0]          # 4 x 4: the first grasp's palm pose in the mesh file's frame and units
    joints = dict(zip(mesh.joint_names, mesh.hand_pose[0, 6:]))  # radians, by name
```

``meshes`` are mesh file paths (.obj/.stl, or folders of them) or in-memory ``trimesh.Trimesh``
objects (a dict gives them names). The run is ``dexlite grasp``'s (``tools.grasp.run_grasp_tool``:
the same checks, preparation, synthesis, tests and selection, so the same grasps for the same
seed); its files go to ``out_dir`` when one is given, else to a temporary folder that is removed
once the result is read. Input the tool cannot use raises ``GraspToolError`` with one line naming
the problem.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexlite_pipeline.model.config import ANY_GRASP_TYPE
from dexlite_pipeline.model.shipped import SHIPPED  # the model (and its evaluator) that ship with the package
from dexlite_pipeline.tools.grasp.request import (
    DEFAULT_GRASPS_PER_OBJECT, DEFAULT_MIN_DISTINCT, DEFAULT_TOP_UP_BATCHES, GraspRequest, GraspToolError,
)  # fmt: skip


@dataclass
class MeshGrasps:
    """One mesh's grasps: the kept held grasps (one per distinct grasp unless ``distinct=False``) and why the others failed.

    Poses are DexGraspNet's 28 numbers in the object frame (metres; README, "Grasp store layout");
    ``palm_in_mesh`` gives the same palm poses as 4 x 4 matrices in the mesh file's own frame and units.
    """

    name: str  # the object id (user-<file stem>)
    file: str
    joint_names: tuple[str, ...]  # the joints of hand_pose[:, 6:], in order: the Shadow Hand's 22, or the hand's (``hand=``)
    hand_pose: np.ndarray  # (K, 28) float32; (K, 6 + J) for another hand
    palm_in_mesh: np.ndarray  # (K, 4, 4) float64
    lift_success: np.ndarray  # (K,) bool
    six_dir_success: np.ndarray  # (K,) bool: held against pushes from all six directions
    start_depth_mm: np.ndarray  # (K,) how far the hand starts inside the object
    distinct_label: np.ndarray  # (K,) int: grasps with one label are near-duplicates
    source: np.ndarray  # (K,) "model" or "optimization"
    grasp_type: np.ndarray  # (K,) power, pinch, tripod, lateral or rim
    attempts: int  # grasps tried on this mesh
    held: int  # of those, held in the lift test (distinct or not)
    failures: dict[str, int] = field(default_factory=dict)  # why the others failed: reason -> count
    preparation: dict = field(default_factory=dict)  # how the file became one solid, and its deviation from the file


@dataclass
class GraspResult:
    """Every mesh's grasps, the meshes not tried (with the reason) and the run's wall time."""

    meshes: dict[str, MeshGrasps]
    rejected: list[dict]
    seconds: float
    out_dir: Path | None  # where the files are (None: not kept)


def grasp_request(
    meshes: list[str], out_dir: str, n: int = DEFAULT_GRASPS_PER_OBJECT, units: str | None = None, *, model: str | None = SHIPPED,
    evaluator: str | None = SHIPPED, from_scratch: bool = False, min_distinct: int | None = None, top_up_batches: int | None = None,
    resize_to_training: bool = False, distinct: bool = True, overwrite: bool = False, device: str | None = None,
    config: dict | None = None, threads: int = 1, renders: int = 0, upright_axis: str | None = None, grasp_type: str | None = None,
    hand: str | None = None, type_rounds: int | None = None,
) -> GraspRequest:
    """The ``GraspRequest`` for these options, refusing contradictory ones (``GraspToolError``).

    ``model``: a cvae.pt, or ``SHIPPED`` (also None); ``evaluator``: an evaluator.pt, ``SHIPPED`` (the shipped model's own
    evaluator, none for another model) or None (the model's first samples, unranked). ``grasp_type``: ``any`` or one of
    power, pinch, tripod, lateral, rim (None: the config's ``sample.grasp_type``); one type sets ``sample.grasp_type`` and makes
    optimization from scratch (``--from-scratch``, the top-up) that type only (``optimize_grasps.grasp_types``). ``hand``:
    shadow, allegro, leap or an MJCF file (config key ``hand``; None: the config's, shadow by default); ``SHIPPED``
    is the model (and evaluator) shipped for that hand (``model.shipped``); a hand without one needs a ``model``
    trained for it or ``from_scratch``; a model of another hand is refused in one line. ``type_rounds``: with
    ``from_scratch``, each object's ``n`` starts in that many rounds, every round after the first dealt to the grasp
    types that held on the object (``tools.grasp.type_rounds``; None: one round, the configured shares).
    """
    from dexlite_pipeline.model.shipped import missing_shipped_model_reason, shipped_evaluator_path, shipped_model_path

    if from_scratch and model not in (None, SHIPPED):
        raise GraspToolError("--model and --from-scratch exclude each other (a model samples grasps; --from-scratch optimizes without one)")
    if from_scratch and min_distinct is not None:
        raise GraspToolError("--min-distinct and --from-scratch exclude each other (--min-distinct tops up a model's grasps "
                             "with optimization from scratch; --from-scratch uses optimization only)")  # fmt: skip
    if from_scratch and top_up_batches is not None:
        raise GraspToolError("--top-up-batches and --from-scratch exclude each other (the top-up adds optimization from scratch to a "
                             "model's grasps; --from-scratch uses optimization only)")  # fmt: skip
    if resize_to_training and units:
        raise GraspToolError("--units and --resize-to-training exclude each other (resized objects take the training radii whatever their unit)")
    if type_rounds is not None and not from_scratch:
        raise GraspToolError("--type-rounds needs --from-scratch (it deals optimization's starts to grasp types; a model samples its own)")
    if type_rounds is not None and not 1 <= type_rounds <= n:
        raise GraspToolError(f"--type-rounds {type_rounds}: expected 1 to --n ({n}), so that every round has a start per object")
    if from_scratch and evaluator not in (None, SHIPPED):
        raise GraspToolError("--evaluator and --from-scratch exclude each other (the evaluator ranks a model's samples)")
    config = typed_config(config or {}, grasp_type) if grasp_type is not None else dict(config or {})
    if hand is not None:
        config["hand"] = str(hand)
    model_file, evaluator_file = None, None
    if not from_scratch:
        model_file = model
        hand_name = str(config.get("hand", "shadow"))
        if model in (None, SHIPPED):
            if shipped_model_path(hand_name) is None:
                raise GraspToolError(f"{missing_shipped_model_reason(hand_name)}: pass --model FILE or --from-scratch")
            model_file = str(shipped_model_path(hand_name))
        if evaluator == SHIPPED:  # the shipped model's own evaluator; another model has none by default
            shipped = shipped_evaluator_path(hand_name) if model in (None, SHIPPED) else None
            evaluator_file = str(shipped) if shipped else None
        else:
            evaluator_file = evaluator
    return GraspRequest(
        meshes=[str(m) for m in meshes], out_dir=str(out_dir), grasps_per_object=n, units=units or "m", resize_to_training=resize_to_training,
        distinct=distinct, overwrite=overwrite, device=device, model=model_file, evaluator=evaluator_file,
        min_distinct=DEFAULT_MIN_DISTINCT if min_distinct is None else min_distinct,
        top_up_batches=DEFAULT_TOP_UP_BATCHES if top_up_batches is None else top_up_batches,
        config=config, threads=threads, renders_per_object=renders, upright_axis=upright_axis,
        grasp_type=grasp_type or (config.get("sample") or {}).get("grasp_type", ANY_GRASP_TYPE), type_rounds=type_rounds or 1,
    )  # fmt: skip


def typed_config(config: dict, grasp_type: str) -> dict:
    """``config`` with ``sample.grasp_type`` set to ``grasp_type`` and, for one type, optimization from scratch making only
    that type (its share 1, the others 0); ``GraspToolError`` for a name that is not a grasp type."""
    from dexlite_pipeline.model.config import GRASP_TYPE_NAMES

    if grasp_type not in (ANY_GRASP_TYPE, *GRASP_TYPE_NAMES):
        raise GraspToolError(f"--grasp-type {grasp_type}: expected {ANY_GRASP_TYPE} or one of {', '.join(GRASP_TYPE_NAMES)}")
    typed = {**config, "sample": {**(config.get("sample") or {}), "grasp_type": grasp_type}}
    if grasp_type != ANY_GRASP_TYPE:
        shares = {name: float(name == grasp_type) for name in GRASP_TYPE_NAMES}
        typed["optimize_grasps"] = {**(config.get("optimize_grasps") or {}), "grasp_types": shares}
    return typed


def _mesh_files(meshes, folder: Path) -> list[str]:
    """Paths for ``meshes``: paths as given; in-memory meshes written to ``folder`` as .obj (named by the dict's keys)."""
    import trimesh

    items = list(meshes.items()) if isinstance(meshes, dict) else [(None, m) for m in ([meshes] if isinstance(meshes, (str, Path, trimesh.Trimesh)) else meshes)]
    files = []
    for k, (name, mesh) in enumerate(items):
        if isinstance(mesh, trimesh.Trimesh):
            path = folder / f"{name or f'mesh_{k}'}.obj"
            if path.exists():
                raise GraspToolError(f"two in-memory meshes named {path.stem!r}")
            folder.mkdir(parents=True, exist_ok=True)
            mesh.export(path)
            files.append(str(path))
        elif isinstance(mesh, (str, Path)):
            files.append(str(mesh))
        else:
            raise GraspToolError(f"mesh {name or k}: expected a file path or a trimesh.Trimesh, got {type(mesh).__name__}")
    if not files:
        raise GraspToolError("no meshes given")
    return files


def palm_matrices_in_mesh_frame(hand_pose: np.ndarray, scale: np.ndarray, meta: dict) -> np.ndarray:
    """(K, 4, 4) palm poses in the mesh file's frame and units: the rotation is the object frame's (same axes), the
    position p / scale / normalization_factor + normalization_centre (README, "Grasp store layout")."""
    from scipy.spatial.transform import Rotation

    matrices = np.tile(np.eye(4), (len(hand_pose), 1, 1))
    if len(hand_pose):
        matrices[:, :3, :3] = Rotation.from_euler("xyz", np.asarray(hand_pose[:, 3:6], np.float64)).as_matrix()
        position = np.asarray(hand_pose[:, :3], np.float64) / np.asarray(scale, np.float64)[:, None] / meta["normalization_factor"]
        matrices[:, :3, 3] = position + np.asarray(meta["normalization_centre"])
    return matrices


def read_result(out_dir: Path, seconds: float, rejected: list[dict], keep: bool) -> GraspResult:
    """The result of a finished run from its output folder (``grasps.zarr``, ``all_grasps.zarr``, the objects' meta.json)."""
    import json

    from dexlite_pipeline.io.grasp_store import hand_joint_names, pose_width, read_grasp_store
    from dexlite_pipeline.tools.grasp.summary import failure_counts

    every = read_grasp_store(out_dir / "all_grasps.zarr")
    kept = read_grasp_store(out_dir / "grasps.zarr") if (out_dir / "grasps.zarr").exists() else None
    held_all = np.asarray(every.arrays["lift_success"], bool)
    meshes = {}
    for object_id in sorted(set(every.object_id.tolist())):
        meta = json.loads((out_dir / "objects" / "assets" / object_id / "meta.json").read_text())
        mine = every.object_id == object_id
        rows = kept.object_id == object_id if kept is not None else np.zeros(0, bool)
        pose = np.asarray(kept.hand_pose[rows]) if kept is not None else np.zeros((0, pose_width(every.attrs)), np.float32)
        scale = np.asarray(kept.scale[rows]) if kept is not None else np.zeros(0, np.float32)

        def column(name, dtype):
            return np.asarray(kept.arrays[name], dtype)[rows] if kept is not None else np.zeros(0, dtype)

        meshes[object_id] = MeshGrasps(
            name=object_id, file=meta["file"], joint_names=tuple(hand_joint_names(every.attrs)), hand_pose=pose,
            palm_in_mesh=palm_matrices_in_mesh_frame(pose, scale, meta), lift_success=column("lift_success", bool),
            six_dir_success=column("six_dir_success", bool), start_depth_mm=column("initial_penetration_mm", np.float64),
            distinct_label=column("distinct_label", np.int64), source=column("source", object), grasp_type=column("grasp_type", object),
            attempts=int(mine.sum()), held=int(held_all[mine].sum()),
            failures=failure_counts(np.asarray(every.arrays["failure_reason"], dtype=object)[mine & ~held_all]),
            preparation={"route": meta["preparation"], "deviation": meta["deviation"]},
        )  # fmt: skip
    return GraspResult(meshes, rejected, seconds, out_dir if keep else None)


def grasp(meshes, n: int = DEFAULT_GRASPS_PER_OBJECT, units: str | None = None, *, seed: int = 0, out_dir: str | Path | None = None,
          **options) -> GraspResult:
    """Grasps that hold for ``meshes`` (paths, folders, ``trimesh.Trimesh`` objects or a dict of them by name), ``n`` per mesh.

    ``units``: the meshes' length unit (m, cm, mm; default m). ``seed``: the run's seed (the config's). ``threads``
    (default 1): torch's threads during the run, as ``dexlite grasp --threads``. ``out_dir``:
    keep ``dexlite grasp``'s files there (summary.md, grasps.zarr, view.html ...); default: none kept. ``options``:
    those of ``grasp_request`` (model, evaluator, from_scratch, min_distinct, top_up_batches, device, config,
    threads, renders, upright_axis, distinct, overwrite, resize_to_training, grasp_type, hand, type_rounds).
    """
    import torch

    from dexlite_pipeline.device import set_threads
    from dexlite_pipeline.tools.grasp.run import run_grasp_tool

    config = {**options.pop("config", {}), "seed": seed}
    threads = options.pop("threads", 1)
    before = torch.get_num_threads()
    set_threads(threads)  # torch runs on ``threads`` threads as the command does (sums in the same order: the same grasps)
    try:
        with tempfile.TemporaryDirectory(prefix="dexlite-grasp-") as scratch:
            files = _mesh_files(meshes, Path(scratch) / "meshes")
            target = Path(out_dir) if out_dir is not None else Path(scratch) / "out"
            outcome = run_grasp_tool(grasp_request(files, str(target), n, units, config=config, threads=threads, **options))
            return read_result(target, outcome.seconds, outcome.rejected, keep=out_dir is not None)
    finally:
        torch.set_num_threads(before)
