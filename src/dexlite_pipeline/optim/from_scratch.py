"""Optimization from scratch: grasps for a group of objects (one shard) by annealed energy optimization.

Every (object, scale) gets ``grasps_per_object`` starts on the inflated convex hull; all
grasps of the shard are optimized together in batches of ``batch_size`` (one batch mixes
objects, so the CPU runs few, large steps), in groups of ``objects_per_energy`` objects when a
shard has more (each group's energy built and released in turn). Each grasp keeps every energy term and a
``passes_energy_thresholds`` flag (DexGraspNet's E_fc < 0.3, E_dis < 5 mm, E_pen < 1 mm).

The default schedule (config.yaml) is DexGraspNet's compressed to 2,000 iterations (step
size and temperature decaying every 17 and 10 iterations), starting 0.1-0.15 m out, with a
contact search every 100 iterations: of the schedules measured it keeps the most
threshold-passing grasps per CPU hour (docs/results.md, the schedule comparison on machine A).

Grasp types (``optim.grasp_types``, ``optimize_grasps.grasp_types``): each object's starts at each scale are dealt
to the types in the configured shares (``assign_types``), each starts from its own type's pose and draws its
contacts from its type's template; every grasp records its type (``grasp_type``). With power grasps only (the
default) the run draws exactly what it drew before grasp types existed.
"""

from __future__ import annotations

import logging
import time
import zlib

import numpy as np
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import TERM_NAMES, GraspEnergy, energy_groups
from dexlite_pipeline.hand.described import is_described
from dexlite_pipeline.hand.model import POSE_DIM, ShadowHand
from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.objects.assets import ObjectAsset
from dexlite_pipeline.optim.annealing import optimize
from dexlite_pipeline.optim.grasp_random import GraspRandom
from dexlite_pipeline.optim.config import OptimizeGraspsConfig
from dexlite_pipeline.optim.grasp_types import POWER_CODE, TYPE_NAMES, assign_types, check_hand_offers, contact_slots, hand_grasp_types, power_slots
from dexlite_pipeline.optim.init import HullSampler, initial_poses
from dexlite_pipeline.optim.type_starts import FLOATING_UP, RimSampler, TypeGeometry, type_start_poses
from dexlite_pipeline.tabletop import store_arrays

log = logging.getLogger(__name__)


def pose_width(hand) -> int:
    """Numbers in one stored pose of ``hand``: the Shadow Hand's ``POSE_DIM`` (28), 6 + J for a hand from its MJCF."""
    return hand.pose_dim if is_described(hand) else POSE_DIM


def start_rows(object_scales: list[tuple[float, ...]], grasps_per_scale: int, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor]:
    """Object index and scale of every start: object-major, then scale-major, ``grasps_per_scale`` of each."""
    object_index = torch.cat([torch.full((grasps_per_scale * len(scales),), i, dtype=torch.long) for i, scales in enumerate(object_scales)])
    scale = torch.cat([torch.tensor(scales, dtype=dtype).repeat_interleave(grasps_per_scale) for scales in object_scales])
    return object_index, scale


def _object_key(object_id: str) -> int:
    """A 32-bit number of an object id (stable across runs and machines)."""
    return zlib.crc32(object_id.encode())


def grasp_keys(assets: list[ObjectAsset], object_index: torch.Tensor) -> torch.Tensor:
    """(B,) each start's key: its object's key and its number among that object's starts (``GraspRandom``'s keys)."""
    index = object_index.cpu()
    number = torch.zeros_like(index)
    for obj in torch.unique(index).tolist():
        rows = (index == obj).nonzero(as_tuple=True)[0]
        number[rows] = torch.arange(len(rows))
    object_keys = torch.tensor([_object_key(a.object_id) for a in assets], dtype=torch.long)
    return object_keys[index] * (1 << 24) + number


def start_types(block_count: int, grasps_per_block: int, shares) -> torch.Tensor:
    """(B,) each start's grasp type (``TYPE_NAMES`` index) for ``start_rows``' blocks of ``grasps_per_block`` starts (one object
    at one scale): every block is dealt to the types in proportion to ``shares`` (type name -> share; ``assign_types``)."""
    return torch.as_tensor(assign_types(shares, grasps_per_block)).repeat(block_count)


class StartDrawer:
    """Start poses of every grasp type for one run's objects: the convex-hull starts of power grasps
    (``optim.init``) and the type starts of the others (``optim.type_starts``, built on first use)."""

    def __init__(self, hand: ShadowHand, assets: list[ObjectAsset], config: OptimizeGraspsConfig, support_planes=None) -> None:
        self.hand, self.assets, self.config, self.support_planes = hand, assets, config, support_planes
        self.hulls = HullSampler(assets)
        self._rims: RimSampler | None = None
        self._geometry: dict[str, TypeGeometry] = {}

    def rims(self) -> RimSampler:
        if self._rims is None:
            up = [FLOATING_UP if self.support_planes is None else self.support_planes.get(a.object_id).normal for a in self.assets]
            self._rims = RimSampler(self.assets, up)
        return self._rims

    def geometry(self, name: str) -> TypeGeometry:
        if name not in self._geometry:
            self._geometry[name] = TypeGeometry(self.hand, hand_grasp_types(self.hand)[name])
        return self._geometry[name]

    def draw(self, object_index: torch.Tensor, scale: torch.Tensor, types: torch.Tensor, generator: torch.Generator,
             support: tuple[torch.Tensor, torch.Tensor] | None) -> torch.Tensor:
        """(B, 28) starts of the given types, type by type in ``TYPE_NAMES`` order from ``generator``."""
        if bool((types == POWER_CODE).all()):
            return initial_poses(self.hand, self.hulls, object_index, scale, self.config.init, generator, support=support)
        init = torch.zeros(len(object_index), pose_width(self.hand), dtype=self.hand.dtype, device=self.hand.device)
        for code, name in enumerate(TYPE_NAMES):
            rows = (types == code).nonzero(as_tuple=True)[0]
            if not len(rows):
                continue
            part = None if support is None else tuple(t[rows.to(t.device)] for t in support)
            obj, sc = object_index[rows.to(object_index.device)], scale[rows.to(scale.device)]
            if code == POWER_CODE:
                init[rows] = initial_poses(self.hand, self.hulls, obj, sc, self.config.init, generator, support=part)
            else:
                init[rows] = type_start_poses(self.hand, hand_grasp_types(self.hand)[name], self.geometry(name), self.hulls, self.rims(), obj, sc,
                                              self.config.init.joint_sigma_fraction, generator, support=part)
        return init


def keyed_starts(starts: StartDrawer, assets: list[ObjectAsset], object_index: torch.Tensor, scale: torch.Tensor, types: torch.Tensor,
                 seed: int, energy: GraspEnergy | None) -> torch.Tensor:
    """(B, 28) starts drawn object by object and type by type, each from a generator of (``seed``, its object's key, and for
    a type other than power its type's number): an object's starts do not depend on the other objects. ``energy``
    (tabletop mode): its support planes keep the palms above the table."""
    hand = starts.hand
    init = torch.zeros(len(object_index), pose_width(hand), dtype=hand.dtype)
    for obj in torch.unique(object_index.cpu()).tolist():
        for code in torch.unique(types).tolist():
            rows = ((object_index.cpu() == obj) & (types == code)).nonzero(as_tuple=True)[0]
            if not len(rows):
                continue
            entropy = [seed, _object_key(assets[obj].object_id)] + ([] if code == POWER_CODE else [code])
            generator = torch.Generator().manual_seed(int(np.random.SeedSequence(entropy).generate_state(1)[0]))
            obj_rows, scale_rows = object_index[rows].to(hand.device), scale[rows].to(hand.device)
            support = energy.support(obj_rows, scale_rows) if energy is not None else None
            init[rows] = starts.draw(obj_rows, scale_rows, types[rows], generator, support).cpu()
    return init


def _optimize_group(
    assets: list[ObjectAsset], config: OptimizeGraspsConfig, energy_config: EnergyConfig, generator: torch.Generator, device,
    support_planes, object_scales: list[tuple[float, ...]], keyed_seed: int | None, hand: ShadowHand,
    type_plans: list[np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """The arrays of ``synthesize`` for one group of objects, optimized with one energy of those objects only."""
    object_index, scale = start_rows(object_scales, config.grasps_per_object, hand.dtype)
    if type_plans is None:
        types = start_types(sum(len(s) for s in object_scales), config.grasps_per_object, config.grasp_types.shares())
    else:  # each object's own plan, the same at each of its scales
        types = torch.cat([torch.as_tensor(np.asarray(plan, dtype=np.int64)).repeat(len(scales)) for plan, scales in zip(type_plans, object_scales)])
    power_only = bool((types == POWER_CODE).all())
    check_hand_offers(hand, [TYPE_NAMES[code] for code in torch.unique(types).tolist()])
    energy = GraspEnergy.from_assets(hand, assets, energy_config, support_planes=support_planes,
                                     max_scale={a.object_id: max(s) for a, s in zip(assets, object_scales)})
    term_names = tuple(term.name for term in energy.terms)
    starts = StartDrawer(hand, assets, config, support_planes)
    total = len(object_index)
    if keyed_seed is not None:
        keys = grasp_keys(assets, object_index)
        keyed_init = keyed_starts(starts, assets, object_index, scale, types, keyed_seed, energy if support_planes is not None else None)
    outputs: dict[str, list] = {k: [] for k in ("hand_pose", "init_pose", "contact_index", "acceptance_rate", "penetration_mm", "contact_distance_mm",
                                                "E_total", "stopped_at_iteration", *term_names)}
    batches = max(1, -(-total // config.batch_size))
    for batch_number, start in enumerate(range(0, total, config.batch_size), start=1):
        rows = slice(start, start + config.batch_size)
        obj = object_index[rows].to(device)
        sc = scale[rows].to(device)
        if keyed_seed is None:
            support = energy.support(obj, sc) if support_planes is not None else None
            init, random = starts.draw(obj, sc, types[rows], generator, support), None
        else:
            init, random = keyed_init[rows].to(device), GraspRandom(keyed_seed, keys[rows])
        slots = power_slots(hand, len(init)) if power_only else contact_slots(hand, types[rows])
        batch_started = time.perf_counter()

        def progress(iteration: int, energy_now: torch.Tensor, batch_number=batch_number, batch_started=batch_started) -> None:
            log.info(
                "batch %d/%d iteration %d/%d: median energy %.4g, %.0f s",
                batch_number, batches, iteration, config.annealing.iterations, float(energy_now.median()), time.perf_counter() - batch_started,
            )

        result = optimize(energy, init, obj, sc, config.optimizer_config(), generator, progress=progress, progress_every=config.progress_every,
                          random=random, contact_slots=slots)
        outputs["hand_pose"].append(result.hand_pose.cpu().numpy())
        outputs["init_pose"].append(init.cpu().numpy())
        outputs["contact_index"].append(result.contact_index.cpu().numpy().astype(np.int16))
        outputs["acceptance_rate"].append(result.acceptance_rate.cpu().numpy())
        outputs["penetration_mm"].append(result.penetration_mm.cpu().numpy())
        outputs["contact_distance_mm"].append(result.contact_distance_mm.cpu().numpy())
        outputs["E_total"].append(result.total.cpu().numpy())
        outputs["stopped_at_iteration"].append(result.stopped_at_iteration.cpu().numpy().astype(np.int32))
        for name in term_names:
            outputs[name].append(result.terms[name].cpu().numpy())
        batch_pass = config.thresholds.passes({**{k: result.terms[k].cpu().numpy() for k in TERM_NAMES}, "penetration_mm": result.penetration_mm.cpu().numpy()})
        log.info("batch %d/%d done: %d grasps in %.0f s, %.1f%% pass the energy thresholds, %d stopped early (hopeless)", batch_number, batches,
                 len(obj), result.seconds, 100 * batch_pass.mean(), int((result.stopped_at_iteration > 0).sum()))

    arrays = {k: np.concatenate(v) if k in ("contact_index", "stopped_at_iteration") else np.concatenate(v).astype(np.float32) for k, v in outputs.items()}
    arrays["object_id"] = np.asarray([assets[i].object_id for i in object_index.tolist()], dtype=object)
    arrays["scale"] = scale.numpy().astype(np.float32)
    arrays["grasp_type"] = np.asarray([TYPE_NAMES[code] for code in types.tolist()], dtype=object)
    arrays["passes_energy_thresholds"] = config.thresholds.passes(arrays)
    if support_planes is not None:
        arrays.update(store_arrays(*support_planes.arrays(arrays["object_id"], arrays["scale"])))
    return arrays


def synthesize(
    assets: list[ObjectAsset],
    config: OptimizeGraspsConfig,
    energy_config: EnergyConfig,
    generator: torch.Generator,
    device: torch.device | str = "cpu",
    support_planes=None,
    object_scales: list[tuple[float, ...]] | None = None,
    keyed_seed: int | None = None,
    hand: ShadowHand | None = None,
    type_plans: list[np.ndarray] | None = None,
) -> tuple[GraspSet, dict]:
    """Optimize ``grasps_per_object`` grasps per object and scale; returns the grasps and run statistics.

    ``support_planes`` (``tabletop.SupportPlanes``; tabletop mode): starts above each object's table,
    E_table in the energy, and the grasps record E_table and their support plane. None: floating objects.
    ``object_scales``: each object's own scales (one tuple per asset, e.g. its real size) instead of
    ``config.scales`` for all; the objects are still optimized together in batches of ``batch_size``.
    More objects than ``config.objects_per_energy`` are optimized in groups of that many, one after the other, each
    with an energy of its own objects only, so memory does not grow with the number of objects (an energy holds ~10-50
    MB an object); with no more objects the run is the one energy's, and keyed draws make it the same for any grouping.
    ``keyed_seed``: every random draw of a grasp (its start and its walk) comes from streams keyed by this seed, its
    object's id and its start number instead of ``generator`` in batch order, so an object's grasps are the same
    whichever other objects are optimized beside it (``keyed_starts``, ``GraspRandom``).
    ``config.grasp_types``: the share of each grasp type among each object's starts (``start_types``); the grasps
    record their type in ``grasp_type``. ``type_plans``: instead, each object's own start types (one array of
    ``grasps_per_object`` ``TYPE_NAMES`` codes per asset, used at each of its scales), e.g. dealt by what held on it.
    ``hand``: the hand to grasp with, on ``device`` (None: the Shadow Hand). A hand from its MJCF
    (``hand.described.DescribedHand``) makes the types its description allows (``optim.described_types``; another type
    is a ValueError), and its poses are 6 + J numbers (its joints); a store of them records the hand
    (``hand.choice.hand_record``, ``io.grasp_store``).
    """
    started = time.process_time()  # CPU seconds (all threads of this process), not wall time
    hand = ShadowHand(device) if hand is None else hand
    if object_scales is None:
        object_scales = [tuple(config.scales)] * len(assets)
    if len(object_scales) != len(assets) or not all(object_scales):
        raise ValueError(f"object_scales: expected one non-empty tuple of scales per object ({len(assets)}), got {object_scales}")
    if type_plans is not None and (len(type_plans) != len(assets) or any(len(plan) != config.grasps_per_object for plan in type_plans)):
        raise ValueError(f"type_plans: expected one plan of {config.grasps_per_object} start types per object ({len(assets)})")
    groups = energy_groups(len(assets), config.objects_per_energy)
    parts = []
    for number, group in enumerate(groups, start=1):
        if len(groups) > 1:
            log.info("objects %d-%d of %d (group %d/%d: optimize_grasps.objects_per_energy = %d)", group.start + 1, group.stop,
                     len(assets), number, len(groups), config.objects_per_energy)
        parts.append(_optimize_group(assets[group], config, energy_config, generator, device, support_planes, object_scales[group],
                                     keyed_seed, hand, None if type_plans is None else type_plans[group]))
    arrays = {name: np.concatenate([part[name] for part in parts]) for name in parts[0]}
    total = len(arrays["object_id"])
    seconds = time.process_time() - started
    stats = {
        "grasps": total,
        "passing": int(arrays["passes_energy_thresholds"].sum()),
        "pass_fraction": float(arrays["passes_energy_thresholds"].mean()) if total else 0.0,
        "stopped_early": int((arrays["stopped_at_iteration"] > 0).sum()),
        "grasp_types": {name: int((arrays["grasp_type"] == name).sum()) for name in TYPE_NAMES if (arrays["grasp_type"] == name).any()},
        "seconds": seconds,
        "seconds_per_grasp": seconds / total if total else 0.0,
    }
    return GraspSet(arrays), stats

