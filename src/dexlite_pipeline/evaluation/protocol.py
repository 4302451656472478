"""The evaluation: gather each method's grasps on the evaluated objects, simulate them, tabulate.

Methods (rows of ``metrics.csv``), each read from the pipeline's own outputs:

- ``optimization`` optimization from scratch (the reference), ``results/optimized/shard_*.zarr``;
- ``cvae_raw``     raw CVAE samples, ``results/sample/shard_*.zarr`` rows with method ``cvae_raw``;
- ``cvae_post``    CVAE samples after post-optimization, ``results/post/shard_*.zarr``;
- ``random_post``  random initialization + the same post-optimization budget,
                   ``results/post/random_shard_*.zarr``;
- ``dexgraspnet``  imported DexGraspNet grasps (when configured);
- ``shipped_raw`` / ``shipped_post``  the shipped (pretrained) model's samples on held-out
                   objects it never trained on, raw and post-optimized (rows ``shipped_raw`` of
                   the sampled and post-optimized stores).

Every method goes through the same measurement: energies recomputed by one code path
(contacts = the four candidates nearest the surface, so no method is judged by its own
optimizer's bookkeeping), then the MuJoCo lift and six-direction tests with one set of
physical constants. At most ``grasps_per_object`` grasps per (method, object) are
chosen by a seeded draw, so every method is weighted alike per object. The CVAE methods
and the random-init baseline share one draw over the sampled rows, so they are compared
on the same source rows (same objects and scales; raw and refined: the same samples).
A chosen grasp with an unusable pose or scale is not simulated but stays in the set as a
failure (``invalid_reason``), so emitting NaN poses cannot raise a method's rate.

Equal filtering: every method is drawn from all its attempts (the optimization method too: all its
optimized grasps, not only those its synthesis flagged as passing) and reported twice, per
attempt and after one energy filter: the simulate step computes every grasp's filter energies
with one contact search (``evaluation.filter_energy``), the aggregate step applies
``evaluate.filter_thresholds`` to them; no method is filtered while another is not. The cost
columns divide the seconds of the stages that generated a method's attempts (see
``selection.stage_seconds_per_grasp``) by what those attempts gave: held grasps, distinct held grasps,
and the same after the filter.

Modules: ``evaluation.selection`` draws each method's grasps; this one measures them (energies,
the equal filter's energies, the lift tests, the budget curve, the fit errors; the coverage in the
aggregate step); ``evaluation.tables`` and ``evaluation.convergence`` tabulate the results, and
``evaluation.shards`` runs the simulate and aggregate steps.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Mapping, Sequence

import numpy as np

from dexlite_pipeline.config import from_section
from dexlite_pipeline.evaluation import metrics
from dexlite_pipeline.evaluation.config import DiversityConfig, EvaluateConfig, WriteupProtocolConfig
from dexlite_pipeline.evaluation.selection import BUDGET_POSES
from dexlite_pipeline.evaluation.step_keys import with_evaluate_keys
from dexlite_pipeline.io.grasp_store import GraspSet

log = logging.getLogger(__name__)

TABLE_DEPTH = "table_depth_mm"  # deepest hand point below the object's table in its resting pose (mm; both modes)
WRITEUP_PROTOCOL_SUCCESS = "writeup_protocol_lift_success"  # lift success under ``evaluate.writeup_protocol``'s physics
BUDGET_SUCCESS = "budget_lift_success"  # (N, S) lift success of the ``selection.BUDGET_POSES`` poses (1/0; NaN where a method has none)
FIT_ERRORS = ("fit_rotation_error_deg", "fit_translation_error_mm", "fit_joint_error_rad")
FIT_METHODS = ("cvae_recon", "cvae_recon_post")  # rows that reproduce a known grasp (``reference_hand_pose``)


def evaluate_config_from(config: Mapping | None, keys: Sequence[str] | None = None) -> EvaluateConfig:
    """The ``evaluate`` section as a dataclass; with ``keys``, only those keys are read (the others keep defaults).

    A step passes the keys it tracks (``evaluation.step_keys``), so it computes the same from the
    rule's cut-down section as from a whole section given on the command line.
    """
    config = config or {}
    if keys is not None:
        config = with_evaluate_keys(config, keys)
    return from_section(EvaluateConfig, config.get("evaluate"), "config.evaluate")


def require_split_objects(split_of: Mapping[str, str], splits: Sequence[str], objects_dirs: Sequence) -> None:
    """Fail when an evaluated split has no object in the catalogs: it would give empty rows, not a result."""
    present = set(split_of.values())
    empty = [split for split in splits if split not in present]
    if empty:
        raise ValueError(
            f"config.evaluate.splits: no object of split {', '.join(empty)} in the catalogs of "
            f"{', '.join(map(str, objects_dirs)) or '(no objects dir)'} (their splits: {', '.join(sorted(present)) or 'none'})"
        )


def simulate(
    selected: GraspSet,
    objects_dirs,
    lift_cfg,
    energy_cfg,
    device: str,
    threads: int,
    energy_batch_size: int,
    writeup_protocol: WriteupProtocolConfig | None = None,
    support_planes=None,
    hand=None,
) -> GraspSet:
    """Energies, the equal filter's energies (``evaluation.filter_energy``) and lift (+ six-direction) results for every
    selected grasp, as one grasp set.

    Invalid grasps (``invalid_reason``) pass through both with NaN results and a failed
    lift; the seconds per grasp are per simulated (valid) grasp. ``support_planes`` (tabletop
    mode): every lift test (and the write-up's protocol's) runs with each object on its table. ``hand``: the hand
    model of the poses (energies, the filter's contact candidates, the lift test's scene; None: the Shadow Hand).
    """
    from dexlite_pipeline.energy.per_grasp import evaluate_grasp_energies
    from dexlite_pipeline.evaluation.filter_energy import filter_energy_arrays
    from dexlite_pipeline.sim.lift import run_lift_tests

    arrays = dict(selected.arrays)
    if len(selected) == 0:
        return GraspSet(arrays, dict(selected.attrs))
    simulated_count = max(1, len(selected) - int(metrics.invalid_flags(arrays).sum()))
    start = time.perf_counter()
    log.info("energies of %d grasps (batches of %d) ...", len(selected), energy_batch_size)
    energies = evaluate_grasp_energies(selected, objects_dirs, device=device, batch_size=energy_batch_size, config=energy_cfg, hand=hand)
    energy_s = time.perf_counter() - start
    log.info("energies of %d grasps in %.1f s (%.1f grasps/s)", len(selected), energy_s, len(selected) / max(energy_s, 1e-9))
    arrays.update(energies)
    start = time.perf_counter()
    arrays.update(filter_energy_arrays(selected, objects_dirs, energy_cfg.weights, device, hand=hand))
    log.info("the equal filter's contact search of %d grasps in %.1f s", len(selected), time.perf_counter() - start)
    start = time.perf_counter()
    lifted = run_lift_tests(selected, objects_dirs, lift_cfg, threads, support_planes=support_planes, hand=hand)
    lifted.pop("table_depth_mm", None)  # measured for every mode by the caller (energy.table_clearance.grasp_table_depths)
    too_deep = np.asarray(lifted["lift_success"], bool) & (np.asarray(lifted["initial_penetration_mm"]) > 1000.0 * lift_cfg.max_initial_penetration_m + 1e-4)
    if too_deep.any():  # the lift test refuses such starts; a held one would mean the start check was bypassed
        raise RuntimeError(f"{int(too_deep.sum())} held grasps start deeper than lift.max_initial_penetration_m ({lift_cfg.max_initial_penetration_m} m)")
    arrays.update(lifted)
    lift_s = time.perf_counter() - start
    if writeup_protocol is not None and writeup_protocol.enabled:
        lenient = dataclasses.replace(lift_cfg, **writeup_protocol.lift_overrides())
        log.info("lift test of %d grasps under the write-up's protocol (friction %g, +%g rad, ratio %g)", len(selected),
                 lenient.friction, lenient.preclose_rad, lenient.success_lift_ratio)
        arrays[WRITEUP_PROTOCOL_SUCCESS] = run_lift_tests(selected, objects_dirs, lenient, threads, support_planes=support_planes,
                                                          hand=hand)["lift_success"]
    attrs = dict(selected.attrs)
    attrs["energy_seconds_per_grasp"] = energy_s / simulated_count
    attrs["simulation_seconds_per_grasp"] = lift_s / simulated_count
    return GraspSet(arrays, attrs)


def simulate_budget(selected: GraspSet, objects_dirs, lift_cfg, threads: int, support_planes=None, hand=None) -> np.ndarray:
    """(N, S) lift success (1.0 / 0.0, lift test only) of each selected grasp's pose after every budget iteration
    (``hand``: the poses' hand model, None: the Shadow Hand).

    The six-direction test is left out here: the budget curve asks how soon post-optimization
    reaches a grasp that holds, and the lift test alone is ten times cheaper.
    """
    import dataclasses

    from dexlite_pipeline.sim.lift import run_lift_tests

    poses = np.asarray(selected.arrays[BUDGET_POSES], dtype=np.float32)
    count, steps = poses.shape[:2]
    flat = GraspSet(
        {
            "hand_pose": poses.reshape(count * steps, -1),
            "object_id": np.repeat(np.asarray(selected.object_id, dtype=object), steps),
            "scale": np.repeat(np.asarray(selected.scale, dtype=np.float32), steps),
        },
        {},
    )
    result = run_lift_tests(flat, objects_dirs, dataclasses.replace(lift_cfg, six_directions=False), threads, support_planes=support_planes,
                            hand=hand)
    return np.asarray(result["lift_success"], dtype=np.float64).reshape(count, steps)


def fit_error_arrays(selected: GraspSet, method: str, sampled_reference: np.ndarray | None) -> dict[str, np.ndarray]:
    """Per-row pose errors against the known grasp a fit-rung row reconstructs; NaN for rows of other methods.

    ``sampled_reference`` is the sampled stores' ``reference_hand_pose`` (rows as in
    ``sample_row``): the training grasp each reconstruction (and its post-optimized version) stands for.
    """
    import torch

    from dexlite_pipeline.model.pose import pose_errors

    out = {name: np.full(len(selected), np.nan) for name in FIT_ERRORS}
    if method not in FIT_METHODS or sampled_reference is None or not len(selected):
        return out
    reference = np.asarray(sampled_reference, dtype=np.float32)[np.asarray(selected.arrays["sample_row"])]
    pose = np.asarray(selected.hand_pose, dtype=np.float32)
    usable = np.isfinite(reference).all(axis=1) & np.isfinite(pose).all(axis=1)
    if usable.any():
        errors = pose_errors(torch.as_tensor(pose[usable]), torch.as_tensor(reference[usable]))
        for name, values in zip(FIT_ERRORS, errors):
            out[name][usable] = values.numpy()
    return out


def coverage_arrays(simulated: GraspSet, objects_dirs, diversity: DiversityConfig, hand=None) -> dict[str, np.ndarray]:
    """The surface patches each grasp touches, for the coverage columns (``metrics.TOUCHED_PATCHES`` and ``COVERAGE_PATCHES``).

    Per object: its stored surface samples split into ``diversity.coverage_patches`` patches
    (``diversity.surface_patch_labels``, in the normalized frame, so one split serves every
    scale); per valid grasp, the hand's 140 contact candidates placed by forward kinematics,
    their signed distance from the object's SDF grid, and the patches touched
    (``diversity.touched_patches``). Invalid grasps and objects whose asset cannot be read
    touch nothing and get 0 patches (coverage NaN for such an object, with a warning). ``hand``: the grasps' hand
    model (None: the Shadow Hand; a ``DescribedHand``'s own contact candidates otherwise).
    """
    import torch

    from dexlite_pipeline.evaluation.diversity import surface_patch_labels, touched_patches
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.objects.assets import ObjectAssetError, SdfBank, load_asset

    n = len(simulated)
    touched = np.zeros((n, diversity.coverage_patches), dtype=bool)
    patches = np.zeros(n, dtype=np.int64)
    if n == 0:
        return {metrics.TOUCHED_PATCHES: touched, metrics.COVERAGE_PATCHES: patches}
    hand = ShadowHand() if hand is None else hand
    object_ids = np.asarray([str(o) for o in simulated.object_id])
    valid = ~metrics.invalid_flags(simulated.arrays)
    for object_id in sorted(set(object_ids)):
        try:
            asset = load_asset(objects_dirs, object_id)
        except ObjectAssetError as exc:
            log.warning("coverage: %s: %s; its coverage is not measured", object_id, exc)
            continue
        labels = surface_patch_labels(asset.surface_points, diversity.coverage_patches)
        rows = np.flatnonzero((object_ids == object_id) & valid)
        patches[object_ids == object_id] = int(labels.max()) + 1 if labels.size else 0
        if not rows.size or not labels.size:
            continue
        bank = SdfBank([asset])
        pose = torch.as_tensor(np.asarray(simulated.hand_pose[rows], dtype=np.float32), dtype=hand.dtype)
        scale = torch.as_tensor(np.asarray(simulated.scale[rows], dtype=np.float32), dtype=hand.dtype)
        with torch.no_grad():
            candidates = hand.contact_candidates(hand.forward(pose))
            distance, _ = bank.signed_distance(candidates, torch.zeros(len(rows), dtype=torch.long), scale, with_normal=False)
        normalized = (candidates / scale[:, None, None]).numpy()  # the surface samples' frame
        found = touched_patches(normalized, distance.numpy(), asset.surface_points, labels, diversity.coverage_contact_m)
        touched[rows, : found.shape[1]] = found
    return {metrics.TOUCHED_PATCHES: touched, metrics.COVERAGE_PATCHES: patches}
