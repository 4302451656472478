"""``dexlite grasp --from-scratch --type-rounds R``: each object's starts in rounds, the later rounds dealt by Thompson
sampling to the grasp types that held on that object; the first round is the run without rounds."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from described_hands import one_line_cli_error  # noqa: E402

from dexlite_pipeline.cli import main  # noqa: E402
from dexlite_pipeline.io.grasp_store import GraspSet, read_grasp_store  # noqa: E402
from dexlite_pipeline.optim.grasp_types import TYPE_NAMES  # noqa: E402
from dexlite_pipeline.tools.grasp.synthesis import concatenate_sources  # noqa: E402
from dexlite_pipeline.tools.grasp.type_rounds import optimize_in_rounds, plan_rng, round_seed, round_sizes, thompson_plan  # noqa: E402

TINY = {
    "objects": {"sdf_resolution": 32, "surface_points": 512, "coacd_mcts_iterations": 10, "coacd_mcts_nodes": 5,
                "coacd_mcts_max_depth": 1, "coacd_resolution": 300},
    "energy": {"object_point_spacing_m": 0.004},
    "optimize_grasps": {"annealing": {"iterations": 30}, "final_contact_samples": 16, "contact_search_every": 0,
                        "grasp_types": {"power": 1.0, "pinch": 1.0}},
}  # fmt: skip


def test_rounds_split_the_starts_evenly_and_refuse_more_rounds_than_starts():
    assert round_sizes(16, 1) == [16] and round_sizes(16, 2) == [8, 8] and round_sizes(7, 3) == [3, 2, 2]
    for n, rounds in ((4, 5), (4, 0)):
        with pytest.raises(ValueError, match="type rounds"):
            round_sizes(n, rounds)
    assert round_seed(7, 0) == 7 and len({round_seed(7, 1), round_seed(7, 2), round_seed(8, 1)}) == 3


def test_thompson_plan_favours_the_type_that_held_and_still_tries_the_others():
    names = ["power", "pinch", "tripod"]
    tried, held = np.array([4, 4, 4]), np.array([4, 0, 0])
    plan = thompson_plan(names, tried, held, 400, plan_rng(0, "user-carton", 1))
    share = np.bincount(plan, minlength=len(TYPE_NAMES)) / len(plan)
    assert set(plan.tolist()) <= {TYPE_NAMES.index(n) for n in names}
    assert share[TYPE_NAMES.index("power")] > 0.9 and 0 < share[TYPE_NAMES.index("pinch")] < 0.1  # Beta(5,1) against Beta(1,5)
    untried = thompson_plan(names, np.zeros(3, int), np.zeros(3, int), 600, plan_rng(0, "user-carton", 1))
    assert all(150 < c < 250 for c in np.bincount(untried)[[TYPE_NAMES.index(n) for n in names]])  # uniform priors: about a third each
    again = thompson_plan(names, tried, held, 400, plan_rng(0, "user-carton", 1))
    other = thompson_plan(names, tried, held, 400, plan_rng(0, "user-spatula", 1))
    assert np.array_equal(plan, again) and not np.array_equal(plan, other)  # seeded per object and round


class _Asset:
    def __init__(self, object_id: str) -> None:
        self.object_id = object_id


def test_later_rounds_go_to_the_type_that_held_on_each_object():
    """A fake optimizer and test: on the carton only power grasps hold, on the spatula only pinches."""
    assets = [_Asset("carton"), _Asset("spatula")]
    holds = {"carton": "power", "spatula": "pinch"}
    calls = []

    def optimize(n, seed, plans):
        calls.append((n, seed, plans))
        rows = {a.object_id: (plans[a.object_id] if plans else np.array([TYPE_NAMES.index("power"), TYPE_NAMES.index("pinch")] * (n // 2)))
                for a in assets}  # fmt: skip
        object_id = np.array([o for o, codes in rows.items() for _ in codes], dtype=object)
        types = np.array([TYPE_NAMES[c] for codes in rows.values() for c in codes], dtype=object)
        return GraspSet({"hand_pose": np.zeros((len(types), 28), np.float32), "object_id": object_id, "scale": np.ones(len(types), np.float32),
                         "grasp_type": types}, {})  # fmt: skip

    def test(grasps):
        grasps.arrays["lift_success"] = np.array([holds[o] == t for o, t in zip(grasps.object_id, grasps.arrays["grasp_type"])])
        return grasps

    tested = optimize_in_rounds(assets, 24, 3, {"power": 1.0, "pinch": 1.0, "tripod": 0.0}, 5, lambda n: n, optimize, test, concatenate_sources)
    assert [c[0] for c in calls] == [8, 8, 8] and [c[1] for c in calls] == [5, round_seed(5, 1), round_seed(5, 2)]
    assert calls[0][2] is None and all(len(plan) == 8 for c in calls[1:] for plan in c[2].values())
    types = np.asarray(tested.arrays["grasp_type"])
    for object_id, good in holds.items():
        mine = np.asarray(tested.object_id) == object_id
        assert mine.sum() == 24 and (types[mine] == good).sum() >= 17  # 4 of the first 8, then most of the next 16
        assert set(types[mine]) <= {"power", "pinch"}  # a type with no share never gets a start


def test_one_type_makes_rounds_a_plain_split_of_the_starts():
    assets = [_Asset("box")]
    plans_seen = []

    def optimize(n, seed, plans):
        plans_seen.append(plans)
        return GraspSet({"hand_pose": np.zeros((n, 28), np.float32), "object_id": np.array(["box"] * n, dtype=object),
                         "scale": np.ones(n, np.float32), "grasp_type": np.array(["power"] * n, dtype=object)}, {})  # fmt: skip

    def test(grasps):
        grasps.arrays["lift_success"] = np.ones(len(grasps), bool)
        return grasps

    tested = optimize_in_rounds(assets, 6, 2, {"power": 1.0}, 0, lambda n: n, optimize, test, concatenate_sources)
    assert len(tested) == 6 and plans_seen == [None, None]


@pytest.mark.slow
def test_grasp_from_scratch_in_rounds_keeps_the_first_round_and_records_the_rounds(tmp_path, capsys):
    box = tmp_path / "box.obj"
    trimesh.creation.box((0.06, 0.05, 0.04)).export(box)
    common = ["--threads", "1", "--from-scratch", "--renders", "0", "--config-json", json.dumps(TINY)]
    assert main(["grasp", str(box), "--out", str(tmp_path / "rounds"), "--n", "4", "--type-rounds", "2", *common]) in (0, 1)
    assert main(["grasp", str(box), "--out", str(tmp_path / "first"), "--n", "2", *common]) in (0, 1)
    rounds = read_grasp_store(tmp_path / "rounds" / "all_grasps.zarr")
    first = read_grasp_store(tmp_path / "first" / "all_grasps.zarr")
    assert len(rounds) == 4 and rounds.attrs["type_rounds"] == 2 and first.attrs["type_rounds"] == 1
    assert np.array_equal(rounds.hand_pose[:2], first.hand_pose)  # round one is the run of its size without rounds
    assert set(rounds.arrays["grasp_type"]) <= {"power", "pinch"} and "in 2 rounds" in rounds.attrs["method"]

    error = one_line_cli_error(capsys, ["grasp", str(box), "--out", str(tmp_path / "x"), "--n", "4", "--type-rounds", "2"])
    assert "--type-rounds needs --from-scratch" in error
    error = one_line_cli_error(capsys, ["grasp", str(box), "--out", str(tmp_path / "y"), "--n", "4", "--type-rounds", "5", "--from-scratch"])
    assert "--type-rounds 5: expected 1 to --n (4)" in error
