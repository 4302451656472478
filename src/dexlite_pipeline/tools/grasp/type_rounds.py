"""Optimization from scratch in rounds: each later round deals an object's starts to the grasp types that held on it.

The configured grasp type shares (``optimize_grasps.grasp_types``) are a guess made before any object is seen, and one
object may hold with one type only: a tall carton with power grasps, a spatula lying on a table with pinches and
tripods. ``dexlite grasp --from-scratch --type-rounds R`` splits each object's ``n`` starts into R rounds
(``round_sizes``). The first round is dealt by the configured shares, optimized and lift-tested as without rounds;
every start of a later round goes to a type by Thompson sampling: each type with a positive share draws a number from
Beta(1 + held, 1 + tested - held), its starts on this object so far (a start stopped early as hopeless counts as tested
and not held), and the start takes the type of the largest draw. A type that held more often gets more of the
starts, one that held rarely or was not tried yet still gets some. The draws come from a generator seeded by the
run's seed, the object's id and the round, so a run is repeatable and an object's plan does not depend on the other
objects. Rounds change nothing with one configured type.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.objects.assets import ObjectAsset


def round_sizes(n: int, rounds: int) -> list[int]:
    """``n`` starts per object split into ``rounds`` rounds as evenly as possible, the earlier rounds one larger;
    ValueError unless 1 <= rounds <= n."""
    if not 1 <= rounds <= n:
        raise ValueError(f"type rounds: expected 1 to {n} (the grasps per object), got {rounds}")
    return [n // rounds + (r < n % rounds) for r in range(rounds)]


def round_seed(seed: int, round_number: int) -> int:
    """The optimization seed of round ``round_number`` (0-based): round 0 has ``seed``, so a run of one round is the run
    without rounds; later rounds get independent streams derived from (seed, round)."""
    return seed if round_number == 0 else int(np.random.SeedSequence([seed, 0x7E5, round_number]).generate_state(1)[0])


def type_tallies(tested: GraspSet, type_names: list[str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Object id -> (tested, held) start counts of each of ``type_names`` on that object in ``tested``."""
    from dexlite_pipeline.io.grasp_store import grasp_types

    objects = np.asarray(tested.object_id, dtype=object)
    types = grasp_types(tested)
    held = np.asarray(tested.arrays["lift_success"], bool)
    of_type = [types == name for name in type_names]
    tallies = {}
    for object_id in dict.fromkeys(objects.tolist()):
        mine = objects == object_id
        tallies[object_id] = (np.array([int((mine & t).sum()) for t in of_type]), np.array([int((mine & t & held).sum()) for t in of_type]))
    return tallies


def thompson_plan(type_names: list[str], tried: np.ndarray, held: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count,) ``TYPE_NAMES`` codes: each start's type is the one whose draw from Beta(1 + held, 1 + tried - held) is largest."""
    from dexlite_pipeline.optim.grasp_types import TYPE_NAMES

    draws = rng.beta(1.0 + held, 1.0 + tried - held, size=(count, len(type_names)))
    codes = np.array([TYPE_NAMES.index(name) for name in type_names], dtype=np.int64)
    return codes[draws.argmax(axis=1)]


def plan_rng(seed: int, object_id: str, round_number: int) -> np.random.Generator:
    """The generator of an object's Thompson draws in one round."""
    return np.random.default_rng([seed, zlib.crc32(object_id.encode()), round_number])


def optimize_in_rounds(
    assets: list[ObjectAsset], n: int, rounds: int, shares: dict[str, float], seed: int, per_scale: Callable[[int], int],
    optimize: Callable[[int, int, dict[str, np.ndarray] | None], GraspSet], test: Callable[[GraspSet], GraspSet],
    concatenate: Callable[[list[GraspSet]], GraspSet],
) -> GraspSet:
    """``n`` tested grasps per object made in ``rounds`` rounds (module docstring).

    ``shares``: the configured type shares (types with a positive share take part); ``per_scale(k)``: the starts at each
    scale for ``k`` grasps per object (the length of a plan); ``optimize(k, seed, plans)``: ``k`` grasps per object
    optimized with that seed and those type plans (object id -> codes; None: the configured shares); ``test``: the
    grasps lift-tested; ``concatenate``: tested sets as one."""
    type_names = [name for name, share in shares.items() if share > 0]
    tested_parts: list[GraspSet] = []
    for round_number, size in enumerate(round_sizes(n, rounds)):
        plans = None
        if round_number and len(type_names) > 1:
            tallies = type_tallies(concatenate(tested_parts), type_names)
            untried = (np.zeros(len(type_names), int), np.zeros(len(type_names), int))
            plans = {
                asset.object_id: thompson_plan(type_names, *tallies.get(asset.object_id, untried), per_scale(size),
                                               plan_rng(seed, asset.object_id, round_number))
                for asset in assets
            }  # fmt: skip
        tested_parts.append(test(optimize(size, round_seed(seed, round_number), plans)))
    return concatenate(tested_parts)
