"""The trained model on disk: a state dict plus the config it was trained with.

Everything in the file is tensors, numbers, strings, lists and dicts, so it loads with
``torch.load(path, weights_only=True)`` (no pickled code is executed). ``grasp_types`` lists the model's type
vocabulary (``model.type_condition``); a file without it (written before grasp types existed) loads as a model
that knows power grasps only, unchanged. ``generator`` names the family (``cvae``, or ``flow`` with its ODE's ``flow``
steps and solver: ``model.flow``); a file without it is a CVAE. ``hand``, ``joint_names`` (and ``hand_sha256`` for a
hand's MJCF file) record the hand the model makes poses of, as a grasp store records it (``hand.choice.hand_record``);
a file without ``hand`` is a Shadow Hand model (every file written before). ``load_checkpoint(..., hand=record)``
refuses a model of another hand in one line naming the file and both hands.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import torch

from dexlite_pipeline.atomic import atomic_path
from dexlite_pipeline.config import json_ready
from dexlite_pipeline.model.config import ModelConfig
from dexlite_pipeline.model.flow import family_record, model_from_record
from dexlite_pipeline.model.hand_match import hand_mismatch, recorded_hand
from dexlite_pipeline.model.network import GraspCVAE

CHECKPOINT_FORMAT = "dexlite-cvae-1"


class CheckpointError(ValueError):
    """A model file that is missing or not a DexLite CVAE checkpoint."""


def save_checkpoint(
    path: str | os.PathLike, model: GraspCVAE, train_config, extra: dict, training_grasps: dict | None = None
) -> Path:
    """Write the model's weights, its ModelConfig, the training config and ``extra`` (JSON-like) atomically.

    ``training_grasps`` ({"hand_pose": (N, 6 + J), "object_id": N strings, "scale": (N,)}) are the
    grasps the model was fitted to, kept so that the learning ladder's *fit* rung can be
    measured from the model file alone.
    """
    payload = {
        "format": CHECKPOINT_FORMAT,
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "model_config": model.config.to_dict(),
        "grasp_types": list(model.type_vocabulary),  # the type vocabulary (model.type_condition); absent: trained before types
        **family_record(model),  # generator (cvae or flow) and a flow's ODE steps; absent: a CVAE
        **json.loads(json.dumps(model.hand_record)),  # hand, joint_names (hand_sha256): the hand the poses are of
        "train_config": json_ready(train_config),
        **json.loads(json.dumps(extra)),
    }
    if training_grasps is not None:
        payload["training_grasps"] = {
            "hand_pose": torch.as_tensor(training_grasps["hand_pose"], dtype=torch.float32).cpu(),
            "object_id": [str(o) for o in training_grasps["object_id"]],
            "scale": torch.as_tensor(training_grasps["scale"], dtype=torch.float32).cpu(),
        }
        if "grasp_type" in training_grasps:
            payload["training_grasps"]["grasp_type"] = [str(t) for t in training_grasps["grasp_type"]]
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)
    return Path(path)


CODE_KEYS = ("codes_mu", "codes_log_var", "codes_condition", "codes_cloud", "codes_type")  # one row per stored training code


def kept_code_rows(cloud: torch.Tensor, grasp_type: torch.Tensor, max_per_cloud: int, seed: int = 0) -> torch.Tensor:
    """Sorted indices of the training codes kept when each training cloud keeps at most ``max_per_cloud`` of its codes:
    a seeded random choice in which a cloud's grasp types take turns (its first pick of each type, then its second of
    each, ...), so a type with few grasps on a cloud keeps them. ``max_per_cloud`` 0: every code."""
    count = len(cloud)
    if max_per_cloud <= 0 or count == 0:
        return torch.arange(count)
    order = torch.randperm(count, generator=torch.Generator().manual_seed(seed))
    cloud, grasp_type = cloud.cpu()[order], grasp_type.cpu()[order]
    # rank of each code among the codes of its (cloud, type) in the random order
    key = cloud * (int(grasp_type.max()) + 1) + grasp_type
    sorted_key, by_key = torch.sort(key, stable=True)
    first = torch.searchsorted(sorted_key, sorted_key, side="left")
    rank = torch.empty(count, dtype=torch.long)
    rank[by_key] = torch.arange(count) - first
    # within a cloud: lower rank first, then the random order; keep the first max_per_cloud
    within = torch.argsort(rank * count + torch.arange(count), stable=True)
    cloud_sorted, by_cloud = torch.sort(cloud[within], stable=True)
    position = torch.arange(count) - torch.searchsorted(cloud_sorted, cloud_sorted, side="left")
    kept = order[within[by_cloud[position < max_per_cloud]]]
    return torch.sort(kept).values


def _capped(payload: dict, max_codes_per_cloud: int, seed: int) -> dict:
    """``payload`` with each training cloud's codes cut to ``max_codes_per_cloud`` (``kept_code_rows``) and ``codes_kept``
    recorded; unchanged for 0 or a file without the codes' clouds. A payload capped before keeps its first record."""
    state = payload["state_dict"]
    if max_codes_per_cloud <= 0 or not len(state.get("codes_cloud", ())) == len(state.get("codes_mu", ())) > 0:
        return payload
    grasp_type = state.get("codes_type", torch.zeros(len(state["codes_mu"]), dtype=torch.long))
    rows = kept_code_rows(state["codes_cloud"], grasp_type, max_codes_per_cloud, seed)
    before = len(state["codes_mu"])
    payload["state_dict"] = {k: v[rows] if k in CODE_KEYS and len(v) == before else v for k, v in state.items()}
    payload.setdefault("codes_kept", {"max_codes_per_cloud": int(max_codes_per_cloud), "seed": int(seed), "before": before, "after": len(rows)})
    return payload


def save_capped_copy(source: str | os.PathLike, destination: str | os.PathLike, max_codes_per_cloud: int, seed: int = 0) -> Path:
    """A float32 copy of a checkpoint whose training clouds keep at most ``max_codes_per_cloud`` codes each (``_capped``):
    the model a shipped half-precision copy with that cap samples like, for measuring it in a run."""
    payload = _capped(torch.load(source, map_location="cpu", weights_only=True), max_codes_per_cloud, seed)
    with atomic_path(destination) as tmp:
        torch.save(payload, tmp)
    return Path(destination)


# A stored copy may keep each training cloud's global feature once (the first columns of codes_condition, the same for
# every code of that cloud) beside each code's own columns: load_checkpoint puts codes_condition back together.
CLOUD_GLOBAL_KEY, CODE_LOCAL_KEY = "cloud_global_condition", "codes_local_condition"


def _split_condition(state: dict, global_width: int) -> dict:
    """``state`` with codes_condition stored as each cloud's global columns once (rows in ``torch.unique(codes_cloud)``
    order) and each code's remaining columns; unchanged when a cloud's codes do not share their global columns."""
    condition, cloud = state.get("codes_condition"), state.get("codes_cloud")
    if condition is None or cloud is None or len(cloud) != len(condition) or not len(cloud):
        return state
    clouds, inverse = torch.unique(cloud, sorted=True, return_inverse=True)
    first = torch.zeros(len(clouds), dtype=torch.long).scatter_reduce(0, inverse, torch.arange(len(cloud)), "amin", include_self=False)
    shared = condition[first, :global_width]
    if not torch.equal(shared[inverse], condition[:, :global_width]):
        return state
    split = {k: v for k, v in state.items() if k != "codes_condition"}
    split[CLOUD_GLOBAL_KEY], split[CODE_LOCAL_KEY] = shared.clone(), condition[:, global_width:].clone()
    return split


def _joined_condition(state: dict) -> dict:
    """``state`` with codes_condition rebuilt from a split store (``_split_condition``); unchanged otherwise."""
    if CODE_LOCAL_KEY not in state:
        return state
    _, inverse = torch.unique(state["codes_cloud"], sorted=True, return_inverse=True)
    joined = {k: v for k, v in state.items() if k not in (CLOUD_GLOBAL_KEY, CODE_LOCAL_KEY)}
    joined["codes_condition"] = torch.cat([state[CLOUD_GLOBAL_KEY][inverse.to(state[CLOUD_GLOBAL_KEY].device)], state[CODE_LOCAL_KEY]], dim=1)
    return joined


def save_half_precision_copy(source: str | os.PathLike, destination: str | os.PathLike, max_codes_per_cloud: int = 0, seed: int = 0) -> Path:
    """A copy of a checkpoint whose weights and latent codes are stored as float16 (about half the
    size: the shipped model). ``load_checkpoint`` restores float32; the training grasps stay float32.

    ``max_codes_per_cloud`` > 0: each training cloud (object and scale) keeps at most that many of its training codes
    (``kept_code_rows``, seeded by ``seed``), so the file's size stops growing with the grasps per object (each code is
    about 2 kB in float16: 54,726 codes are 112 MB); the copy records ``codes_kept`` (the cap, the codes before and after).
    A training cloud's global feature, which every code of that cloud carries, is stored once (``_split_condition``)."""
    payload = _capped(torch.load(source, map_location="cpu", weights_only=True), max_codes_per_cloud, seed)
    payload["state_dict"] = {k: v.half() if v.is_floating_point() else v for k, v in payload["state_dict"].items()}
    payload["state_dict"] = _split_condition(payload["state_dict"], int(payload["model_config"]["pointnet_widths"][-1]))
    payload["stored_dtype"] = "float16"
    with atomic_path(destination) as tmp:
        torch.save(payload, tmp)
    return Path(destination)


def load_checkpoint(path: str | os.PathLike, device: torch.device | str = "cpu", hand: dict | None = None) -> tuple[GraspCVAE, dict]:
    """The model in eval mode on ``device`` and the checkpoint's other entries.

    ``hand``: the hand record the caller works with (``hand.choice.hand_record``); a model of another hand raises
    ``CheckpointError`` in one line naming the file and both hands (``hand_mismatch``). None: any hand.
    """
    p = Path(path)
    if not p.is_file():
        raise CheckpointError(f"{p}: model checkpoint not found")
    try:
        payload = torch.load(p, map_location=device, weights_only=True)
    except Exception as exc:  # torch raises several types for a foreign or corrupt file
        raise CheckpointError(f"{p}: cannot load as a weights-only checkpoint ({exc})") from exc
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{p}: not a {CHECKPOINT_FORMAT} checkpoint")
    model_hand = recorded_hand(payload)
    if hand is not None and (refusal := hand_mismatch(p, model_hand, hand)):
        raise CheckpointError(refusal)
    try:
        model = model_from_record(
            payload, ModelConfig.from_dict(payload["model_config"]), tuple(payload.get("grasp_types") or ()), model_hand
        ).to(device)
    except ValueError as exc:
        raise CheckpointError(f"{p}: {exc}") from exc
    state = {k: v.float() if v.dtype == torch.float16 else v for k, v in _joined_condition(payload["state_dict"]).items()}  # a half-precision copy
    empty = torch.zeros(0, model.config.latent_dim)
    model.set_latent_codes(
        state.pop("codes_mu", empty), state.pop("codes_log_var", empty), state.pop("codes_condition", None), state.pop("codes_cloud", None),
        state.pop("codes_type", None),  # absent in a model trained before grasp types: every code power
    )
    model.load_state_dict(state, strict=False)
    missing = set(model.state_dict()) - set(state) - {"codes_mu", "codes_log_var", "codes_condition", "codes_cloud", "codes_type"}
    unexpected = set(state) - set(model.state_dict())
    if missing or unexpected:
        raise CheckpointError(f"{p}: weights do not match the model config (missing {sorted(missing)[:3]}, unexpected {sorted(unexpected)[:3]})")
    model.eval()
    return model, {k: v for k, v in payload.items() if k != "state_dict"}


def cloud_reading(checkpoint: dict, points_per_cloud: int = 0) -> tuple[int, bool]:
    """How a model reads object clouds: points per cloud (``points_per_cloud``, or as trained when 0) and
    whether each object's cloud is one fixed farthest-point subset (as trained)."""
    trained = checkpoint["train_config"]
    return points_per_cloud or int(trained["points_per_cloud"]), bool(trained.get("fixed_clouds", False))
