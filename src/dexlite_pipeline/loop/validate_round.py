"""A round's checks (stage ``loop_validate``): the equal energy filter, the lift test and the six-direction test of
the refined grasps, each grasp with the reason it is not kept (``drop_reason``, ``round_basics.DROP_REASONS``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store
from dexlite_pipeline.loop.round_basics import ENERGY_FILTER, LIFT_TEST, NOT_OPTIMIZED, SIX_DIRECTIONS


def validate_round(
    post_path: str, objects_dirs: list[str], thresholds, energy_weights, lift, six_directions: bool, threads: int = 1,
    support_planes=None, device: str = "cpu", simulate_all: bool = False, hand=None, hand_name: str | None = None,
) -> GraspSet:
    """The refined grasps of ``post_path`` with the checks a new grasp must pass, and ``drop_reason`` per grasp.

    In order: refined at all (``NOT_OPTIMIZED``), below every threshold of ``thresholds`` (``EnergyThresholds``) with
    the equal filter's contacts (``ENERGY_FILTER``; E_pen and the penetration depth the refined ones), the lift test (``LIFT_TEST``) and, with
    ``six_directions``, the six-direction test (``SIX_DIRECTIONS``); ``lift`` is the ``LiftConfig``, ``support_planes``
    the tables (tabletop mode). Only grasps that passed the checks before are simulated (the others keep NaN results),
    or with ``simulate_all`` every refined grasp (the held-out check: success per attempt, as the evaluation counts it).
    ``hand``: the hand model of the poses (the filter's contact candidates, the lift test's scene; None: the Shadow Hand);
    ``hand_name``: config key ``hand``, which the store's recorded hand must be (``GraspStoreError`` in one line otherwise).
    """
    from dexlite_pipeline.evaluation.filter_energy import FILTER_CONTACTS, FILTER_ENERGIES, filter_energy_arrays
    from dexlite_pipeline.evaluation.metrics import filter_flags
    from dexlite_pipeline.sim.lift import run_lift_tests

    from dexlite_pipeline.model.hand_match import shards_hand

    post = read_grasp_store(post_path)
    shards_hand([(post_path, post.attrs)], hand_name)
    n = len(post)
    arrays = dict(post.arrays)
    reason = np.full(n, "", dtype=object)
    failure = np.asarray(arrays.get("failure_reason", np.full(n, "", dtype=object))).astype(str)
    optimized = (failure == "") & np.isfinite(post.hand_pose).all(axis=1)
    reason[~optimized] = NOT_OPTIMIZED
    rows = np.flatnonzero(optimized)
    found = filter_energy_arrays(post.select(rows), objects_dirs, energy_weights, device, hand=hand)
    arrays[FILTER_CONTACTS] = np.full((n, 4), -1, np.int64)
    for name in FILTER_ENERGIES:
        arrays[name] = np.full(n, np.nan, np.float32)
    for name, values in found.items():
        arrays[name][rows] = values
    # E_pen and the judged depth are the refined pose's; absent when no row was refined
    refined = {name: np.asarray(arrays.get(name, np.full(n, np.nan)), np.float64) for name in ("E_pen", "penetration_mm")}
    passing = filter_flags({"hand_pose": post.hand_pose, **arrays, **refined}, thresholds.limits())
    reason[(reason == "") & ~passing] = ENERGY_FILTER
    rows = np.flatnonzero(optimized if simulate_all else reason == "")
    lift = dataclasses.replace(lift, six_directions=six_directions)
    lifted = run_lift_tests(post.select(rows), objects_dirs, lift, threads, support_planes, hand=hand)
    for name, values in lifted.items():
        arrays["lift_failure_reason" if name == "failure_reason" else name] = _scattered(values, rows, n)
    reason[(reason == "") & ~arrays["lift_success"].astype(bool)] = LIFT_TEST
    if six_directions:
        reason[(reason == "") & ~arrays["six_dir_success"].astype(bool)] = SIX_DIRECTIONS
    arrays["drop_reason"] = reason
    attrs = {**post.attrs, "stage": "loop_validate", "lift_config": lift.as_dict(), "thresholds": thresholds.limits()}
    return GraspSet(arrays, attrs)


def _scattered(values: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    """(n, ...) ``values`` placed at ``rows``; elsewhere "" (strings), False (flags) or NaN (numbers)."""
    values = np.asarray(values)
    if values.dtype == object:
        full = np.full((n, *values.shape[1:]), "", dtype=object)
    elif values.dtype == bool:
        full = np.zeros((n, *values.shape[1:]), dtype=bool)
    else:
        full = np.full((n, *values.shape[1:]), np.nan, dtype=np.float64 if values.dtype.kind in "iu" else values.dtype)
    full[rows] = values
    return full
