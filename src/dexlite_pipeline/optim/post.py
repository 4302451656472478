"""Post-optimization: a short run of the annealed optimizer on E_post from given (CVAE) poses.

E_post = E_fc + 100 E_dis + 100 E_pen + 10 E_spen + E_joints (weights in config). The
optimizer is DexGraspNet's (``optim.annealing.optimize``) with its constants from config
section ``post_optimize``. A CVAE grasp starts from contacts where it already touches
(``start_contacts="surface"``: the best of ``start_contact_samples`` near-surface pad
4-sets, or the four nearest pads), a random start from uniform contacts (DexGraspNet's);
with ``final_contact_samples`` the best contact set for the final pose is searched once
at the end, so the reported E_post is that of the pose, not of a random contact walk.
With ``keep_best`` (default) each grasp ends in the lowest-E_post state it visited: at
the T0 = 18 of the DexLite write-up (Murali) nearly every step is accepted, and the last state of that walk is often
worse than the start. CVAE starts are already close to a grasp, so they run a close-start
schedule (``learned_start_temperature``, ``learned_start_step_size``: T0 0.5, step 0.002 by
default; 18 and 0.005 give the write-up's); random starts keep DexGraspNet's exploring one. The pose after each of ``budget_iterations`` is kept for the budget
curve. The random-init baseline uses the same budget from ``optim.init.initial_poses``
(convex-hull start) for the same objects and scales.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.energy.contact_slots import ContactSlots
from dexlite_pipeline.energy.grasp_energy import TERM_NAMES, GraspEnergy
from dexlite_pipeline.optim.config import PostOptimizeConfig
from dexlite_pipeline.optim.annealing import optimize

# Terms traced per iteration beside E_post: those of DexGraspNet's success thresholds, so the
# evaluation can tell at which iteration each grasp first meets them.
TRACED_TERMS = ("E_fc", "E_dis", "E_pen")

log = logging.getLogger(__name__)

@dataclass
class RefinedGrasps:
    """Per-grasp arrays (numpy) of a post-optimization run, ready for a grasp store."""

    arrays: dict[str, np.ndarray]
    trace_iterations: np.ndarray
    seconds: float  # CPU seconds of this process (all its threads) for the whole refinement: start contacts, optimizer, results


def _log_progress(iteration: int, total: torch.Tensor) -> None:
    log.info("post-optimization iteration %d: median E_post %.4g", iteration, float(total.median()))


def _energy_arrays(prefix: str, result) -> dict[str, np.ndarray]:
    arrays = {f"{prefix}{name}": result.terms[name].detach().cpu().numpy() for name in result.terms}  # TERM_NAMES (+ E_table on a table)
    arrays[f"{prefix}E_post"] = result.total.detach().cpu().numpy()
    arrays[f"{prefix}penetration_mm"] = result.penetration_mm.detach().cpu().numpy()
    arrays[f"{prefix}contact_distance_mm"] = result.contact_distance_mm.detach().cpu().numpy()
    return arrays


def merged_refinement(parts: list[tuple[np.ndarray, RefinedGrasps]], count: int) -> RefinedGrasps:
    """The refinements of row groups (each with its row indices among ``count`` rows) as one, in row order."""
    if len(parts) == 1 and np.array_equal(parts[0][0], np.arange(count)):
        return parts[0][1]
    arrays = {}
    for name, values in parts[0][1].arrays.items():
        merged = np.empty((count, *values.shape[1:]), dtype=values.dtype)
        for rows, part in parts:
            merged[rows] = part.arrays[name]
        arrays[name] = merged
    return RefinedGrasps(arrays=arrays, trace_iterations=parts[-1][1].trace_iterations, seconds=sum(part.seconds for _, part in parts))


def refine(
    energy: GraspEnergy,
    init_pose: torch.Tensor,
    object_index: torch.Tensor,
    scale: torch.Tensor,
    config: PostOptimizeConfig,
    generator: torch.Generator,
    start_contacts: str = "surface",
    slots: ContactSlots | None = None,
) -> RefinedGrasps:
    """Post-optimize ``init_pose`` (B, 28) in batches of ``config.batch_size``.

    ``slots`` (B grasps; ``optim.grasp_types.contact_slots``): each grasp's contacts, at the start, in the walk and in the
    final search, come from its grasp type's contact template only, so a sampled pinch is refined as a pinch; None:
    any pads (power grasps).

    Returns the refined pose (``hand_pose``), the initial one (``raw_hand_pose``), every
    energy term before (``raw_*``) and after, E_post at every iteration (``energy_trace``,
    (B, iterations + 1): of the accepted state, or with ``keep_best`` of the best state so
    far), the thresholded terms at every iteration
    (``trace_E_fc``, ``trace_E_dis``, ``trace_E_pen``), the acceptance rate and the iteration at which a hopeless
    grasp stopped (``stopped_at_iteration``, 0: it ran every iteration; ``post_optimize.stop_hopeless``).
    """
    if start_contacts not in ("surface", "random"):
        raise ValueError(f"start_contacts must be 'surface' or 'random', not {start_contacts!r}")
    annealing = config.optimizer_config(learned_start=start_contacts == "surface")
    started = time.process_time()
    chunks: list[dict[str, np.ndarray]] = []
    trace_iterations = np.arange(config.annealing.iterations + 1)
    for start in range(0, init_pose.shape[0], config.batch_size):
        rows = slice(start, start + config.batch_size)
        pose, obj, sc = init_pose[rows], object_index[rows], scale[rows]
        part = None if slots is None else slots.take(torch.arange(init_pose.shape[0])[rows])
        with torch.no_grad():
            contacts = energy.nearest_contacts(energy.hand.forward(pose), obj, sc, part)
            if config.start_contact_samples > 0:
                contacts = energy.best_contacts(pose, obj, sc, contacts, config.start_contact_samples, generator, slots=part)
            before = energy(pose, object_index=obj, scale=sc, contact_index=contacts)
        contacts = contacts if start_contacts == "surface" else None
        result = optimize(
            energy, pose, obj, sc, annealing, generator, contact_index=contacts, progress=_log_progress, progress_every=50,
            snapshot_iterations=config.budget(), contact_slots=part,
        )
        trace_iterations = result.trace_iterations.cpu().numpy()
        chunk = {
            "hand_pose": result.hand_pose.cpu().numpy(),
            "raw_hand_pose": pose.detach().cpu().numpy(),
            "contact_index": result.contact_index.cpu().numpy().astype(np.int16),
            "acceptance_rate": result.acceptance_rate.cpu().numpy(),
            "stopped_at_iteration": result.stopped_at_iteration.cpu().numpy().astype(np.int32),
            "energy_trace": result.trace.T.cpu().numpy().astype(np.float32),
        }
        for name in TRACED_TERMS:
            chunk[f"trace_{name}"] = result.term_traces[name].T.cpu().numpy().astype(np.float32)
        if config.budget():
            chunk["budget_hand_pose"] = torch.stack([result.snapshots[i] for i in config.budget()], dim=1).cpu().numpy()
        chunk.update(_energy_arrays("raw_", before))
        chunk.update(_energy_arrays("", result))
        chunks.append(chunk)
    arrays = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]} if chunks else {}
    return RefinedGrasps(arrays=arrays, trace_iterations=trace_iterations, seconds=time.process_time() - started)

