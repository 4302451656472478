"""The annealed optimizer: lowers the energy, is deterministic, keeps the stored pose form."""

from __future__ import annotations

import math

import pytest
import torch

from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.energy.grasp_energy import GraspEnergy
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix
from dexlite_pipeline.objects.assets import load_asset
from dexlite_pipeline.optim.annealing import optimize, pose_to_state, state_to_pose
from dexlite_pipeline.optim.config import AnnealingConfig, InitConfig
from dexlite_pipeline.optim.init import HullSampler, initial_poses
from dexlite_pipeline.optim.init import PALM_APPROACH

SHORT = AnnealingConfig(iterations=60, step_size_period=10, temperature_period=5, trace_every=10)


@pytest.fixture(scope="module")
def setup(hand, optim_objects):
    """Energy and hull sampler on the tiny objects; one torch thread (small ops, shared machine)."""
    assets = [load_asset(optim_objects, "sphere"), load_asset(optim_objects, "box")]
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield GraspEnergy.from_assets(hand, assets, EnergyConfig(object_point_spacing_m=0.003)), HullSampler(assets)
    torch.set_num_threads(threads)


def _batch(size: int):
    object_index = torch.arange(size) % 2
    scale = torch.full((size,), 0.08)
    return object_index, scale


def test_pose_state_round_trip():
    pose = torch.rand(16, 28) - 0.5
    pose[:, 3:6] *= 2.0
    back = state_to_pose(pose_to_state(pose))
    assert torch.allclose(euler_xyz_to_matrix(back[:, 3:6]), euler_xyz_to_matrix(pose[:, 3:6]), atol=1e-5)
    assert torch.allclose(back[:, :3], pose[:, :3]) and torch.allclose(back[:, 6:], pose[:, 6:])


def test_initial_poses_face_the_object_from_outside(hand, setup):
    energy, hulls = setup
    object_index, scale = _batch(64)
    config = InitConfig(distance_m=(0.1, 0.15), jitter_deg=30.0)
    pose = initial_poses(hand, hulls, object_index, scale, config, torch.Generator().manual_seed(0))
    assert pose.shape == (64, 28)
    # The palm origin lies 0.1-0.15 m beyond a hull point: at least 0.1 m from the object.
    distance = pose[:, :3].norm(dim=1)
    assert (distance > 0.1).all() and (distance < 0.15 + 0.08 * math.sqrt(3) * 0.8).all()
    # Its approach direction points at the object (within the jitter, and the hull's extent).
    approach = euler_xyz_to_matrix(pose[:, 3:6]) @ torch.tensor(PALM_APPROACH)
    toward_centre = torch.nn.functional.normalize(-pose[:, :3], dim=1)
    assert ((approach * toward_centre).sum(1) > math.cos(math.radians(60))).all()
    limits = hand.joint_limits
    assert ((pose[:, 6:] >= limits[:, 0] - 1e-6) & (pose[:, 6:] <= limits[:, 1] + 1e-6)).all()


def test_starts_on_a_table_put_every_palm_above_it(hand, setup):
    """A table through the objects' middle: half of the floating starts have the palm below it;
    on the table every palm is above it, and with the table far below nothing is redrawn."""
    _, hulls = setup
    object_index, scale = _batch(64)
    config = InitConfig(distance_m=(0.1, 0.15), jitter_deg=30.0)
    up = torch.tensor([0.0, 0.0, 1.0]).expand(64, 3)
    floating = initial_poses(hand, hulls, object_index, scale, config, torch.Generator().manual_seed(0))
    assert (floating[:, 2] < 0).sum() > 10
    tabletop = initial_poses(hand, hulls, object_index, scale, config, torch.Generator().manual_seed(0), support=(up, torch.zeros(64)))
    assert (tabletop[:, 2] >= 0).all()
    far_below = initial_poses(hand, hulls, object_index, scale, config, torch.Generator().manual_seed(0), support=(up, torch.full((64,), 10.0)))
    assert torch.equal(far_below, floating)


def test_top_and_sides_puts_half_the_hull_points_on_the_top_of_the_table_normal(setup):
    """The box (1.2 x 0.9 x 0.7): its top is a fifth of its hull's area; with ``top_and_sides`` half the points are on
    the faces facing the table's normal, whichever axis that is, and the others on the rest; without a table, by area."""
    _, hulls = setup
    rows = 4000
    box = torch.ones(rows, dtype=torch.long)
    _, by_area = hulls.sample(box, torch.Generator().manual_seed(0))
    for axis in range(3):
        up = torch.zeros(rows, 3, dtype=torch.float64)
        up[:, axis] = 1.0
        points, normals = hulls.sample(box, torch.Generator().manual_seed(0), up=up)
        on_top = normals[:, axis] > 0.99
        assert abs(float(on_top.double().mean()) - 0.5) < 0.03
        assert abs(float((by_area[:, axis] > 0.99).double().mean()) - 0.5) > 0.15  # by area no face gets half
        half = float(hulls.triangles[1][..., axis].max())
        assert torch.allclose(points[on_top, axis], torch.full((int(on_top.sum()),), half, dtype=torch.float64))


def test_top_and_sides_starts_come_from_above_half_the_time_and_floating_starts_are_unchanged(hand, setup):
    _, hulls = setup
    object_index, scale = _batch(256)
    up = torch.tensor([0.0, 0.0, 1.0]).expand(256, 3)
    table = (up, torch.full((256,), 0.04))  # the table 4 cm under the objects' centre (the box is 5.6 cm tall at this scale)
    split = InitConfig(distance_m=(0.1, 0.15), jitter_deg=0.0, start_faces="top_and_sides")
    by_area = InitConfig(distance_m=(0.1, 0.15), jitter_deg=0.0)
    assert torch.equal(initial_poses(hand, hulls, object_index, scale, split, torch.Generator().manual_seed(0)),
                       initial_poses(hand, hulls, object_index, scale, by_area, torch.Generator().manual_seed(0)))
    approach = {name: euler_xyz_to_matrix(initial_poses(hand, hulls, object_index, scale, config, torch.Generator().manual_seed(0), support=table)[:, 3:6])
                @ torch.tensor(PALM_APPROACH) for name, config in (("split", split), ("area", by_area))}
    from_above = {name: (a[object_index == 1, 2] < -0.99).double().mean().item() for name, a in approach.items()}
    assert from_above["area"] < 0.3 and abs(from_above["split"] - 0.5) < 0.1


def test_optimizer_lowers_energy_and_records_trace(hand, setup):
    energy, hulls = setup
    object_index, scale = _batch(12)
    generator = torch.Generator().manual_seed(1)
    init = initial_poses(hand, hulls, object_index, scale, InitConfig(distance_m=(0.05, 0.08)), generator)
    result = optimize(energy, init, object_index, scale, SHORT, generator)
    assert result.hand_pose.shape == (12, 28) and result.contact_index.shape == (12, 4)
    assert result.trace.shape == (7, 12)  # initial + every 10 of 60
    assert result.trace_iterations.tolist() == [0, 10, 20, 30, 40, 50, 60]
    assert result.trace[-1].mean() < 0.7 * result.trace[0].mean()
    # Each term is traced at the same rows and its last row is the returned state's term.
    assert set(result.term_traces) == set(result.terms)
    for name, trace in result.term_traces.items():
        assert trace.shape == (7, 12)
        assert torch.equal(trace[-1], result.terms[name])
    # The reported terms belong to the returned pose and contacts.
    again = energy(result.hand_pose, object_index=object_index, scale=scale, contact_index=result.contact_index)
    assert torch.allclose(again.total, result.total, rtol=1e-3, atol=1e-3)
    assert ((result.acceptance_rate > 0) & (result.acceptance_rate <= 1)).all()


def test_optimizer_is_deterministic_for_a_seed(hand, setup):
    energy, hulls = setup
    object_index, scale = _batch(6)
    runs = []
    for _ in range(2):
        generator = torch.Generator().manual_seed(7)
        init = initial_poses(hand, hulls, object_index, scale, InitConfig(), generator)
        runs.append(optimize(energy, init, object_index, scale, AnnealingConfig(iterations=15), generator))
    assert torch.equal(runs[0].hand_pose, runs[1].hand_pose)
    assert torch.equal(runs[0].contact_index, runs[1].contact_index)
    other = optimize(energy, init, object_index, scale, AnnealingConfig(iterations=15), torch.Generator().manual_seed(8))
    assert not torch.equal(other.hand_pose, runs[0].hand_pose)


def test_schedule_constants():
    config = AnnealingConfig()
    assert config.step_size_at(49) == pytest.approx(0.005)
    assert config.step_size_at(50) == pytest.approx(0.005 * 0.95)
    assert config.temperature_at(29) == pytest.approx(18.0)
    assert config.temperature_at(60) == pytest.approx(18.0 * 0.95**2)


def test_contact_search_never_raises_the_final_energy(hand, setup):
    energy, hulls = setup
    object_index, scale = _batch(8)
    init = initial_poses(hand, hulls, object_index, scale, InitConfig(distance_m=(0.05, 0.08)), torch.Generator().manual_seed(3))
    plain = optimize(energy, init, object_index, scale, SHORT, torch.Generator().manual_seed(4))
    searched_config = AnnealingConfig(**{**SHORT.__dict__, "final_contact_samples": 128})
    searched = optimize(energy, init, object_index, scale, searched_config, torch.Generator().manual_seed(4))
    assert torch.equal(searched.hand_pose, plain.hand_pose)  # same walk, only the final contacts differ
    assert (searched.total <= plain.total + 1e-6).all() and (searched.total < plain.total).any()
    during_config = AnnealingConfig(**{**searched_config.__dict__, "contact_search_every": 20})
    during = optimize(energy, init, object_index, scale, during_config, torch.Generator().manual_seed(4))
    assert torch.isfinite(during.total).all() and during.trace.shape == plain.trace.shape


def test_keep_best_returns_the_lowest_energy_state_visited(hand, setup):
    """At a constant high temperature the walk leaves good states; keep_best ends in the best one seen."""
    energy, hulls = setup
    object_index, scale = _batch(8)
    init = initial_poses(hand, hulls, object_index, scale, InitConfig(distance_m=(0.05, 0.08)), torch.Generator().manual_seed(3))
    good = optimize(energy, init, object_index, scale, SHORT, torch.Generator().manual_seed(4))
    hot = AnnealingConfig(iterations=40, temperature_decay=1.0, trace_every=1)
    last = optimize(energy, good.hand_pose, object_index, scale, hot, torch.Generator().manual_seed(5), contact_index=good.contact_index)
    best = optimize(
        energy, good.hand_pose, object_index, scale, AnnealingConfig(**{**hot.__dict__, "keep_best": True}),
        torch.Generator().manual_seed(5), contact_index=good.contact_index,
    )
    start = last.trace[0]
    assert (last.total > start + 1e-4).any()  # the plain walk ends worse than it started for some grasps
    assert (best.total <= start + 1e-5).all()
    assert torch.allclose(best.total, last.trace.min(dim=0).values, atol=1e-5)  # the same walk, its minimum kept
    assert (best.trace[1:] <= best.trace[:-1] + 1e-6).all()
    with torch.no_grad():
        again = energy(best.hand_pose, object_index=object_index, scale=scale, contact_index=best.contact_index)
    assert torch.allclose(again.total, best.total, rtol=1e-4, atol=1e-4)


def test_an_empty_batch_gives_empty_results(setup):
    energy, _ = setup
    pose, object_index, scale = torch.zeros(0, 28), torch.zeros(0, dtype=torch.long), torch.zeros(0)
    assert energy(pose, object_index=object_index, scale=scale).total.shape == (0,)
    result = optimize(energy, pose, object_index, scale, AnnealingConfig(iterations=3, final_contact_samples=4), torch.Generator().manual_seed(0))
    assert result.hand_pose.shape == (0, 28) and result.contact_index.shape == (0, 4)


def test_acceptance_and_keep_best_pieces():
    """Downhill proposals are always accepted; the kept-best state is each grasp's running minimum."""
    from dexlite_pipeline.optim.annealing import KeepBest, WalkState, _Kept, metropolis_accept

    uniform = torch.rand(4, generator=torch.Generator().manual_seed(0))
    old = torch.tensor([1.0, 1.0, 1.0, 5.0])
    assert metropolis_accept(old, old - 0.5, temperature=1e-3, uniform=uniform).all()
    assert not metropolis_accept(old, old + 10.0, temperature=1e-3, uniform=uniform).any()

    def walk(total):
        total = torch.as_tensor(total)
        kept = _Kept({"E_fc": total * 2}, total * 0, total * 0)
        return WalkState(total[:, None].expand(-1, 31).clone(), torch.zeros(len(total), 4, dtype=torch.long), total, kept, torch.zeros(len(total), 31))

    best = KeepBest(walk([3.0, 1.0, 2.0]))
    for totals in ([2.0, 4.0, 2.0], [5.0, 0.5, 1.0]):
        best.update(walk(totals))
    assert best.best.total.tolist() == [2.0, 0.5, 1.0] and best.best.grad is None
    assert best.best.state[:, 0].tolist() == [2.0, 0.5, 1.0] and best.best.result.terms["E_fc"].tolist() == [4.0, 1.0, 2.0]


def test_a_grasp_refines_the_same_alone_and_in_a_batch(hand, setup):
    """With each grasp's own random stream and RMSProp statistic, a grasp's walk does not depend on its batch:
    the same start, key and seed give the same result alone, in a batch of six, and in another order."""
    import dataclasses

    from dexlite_pipeline.optim.grasp_random import GraspRandom

    energy, hulls = setup
    object_index, scale = _batch(6)
    init = initial_poses(hand, hulls, object_index, scale, InitConfig(distance_m=(0.06, 0.09)), torch.Generator().manual_seed(5))
    config = dataclasses.replace(SHORT, rmsprop_statistic="grasp", final_contact_samples=16, contact_search_every=20)
    keys = torch.tensor([11, 12, 13, 14, 15, 16])

    def run(rows):
        return optimize(energy, init[rows], object_index[rows], scale[rows], config, torch.Generator().manual_seed(0),
                        random=GraspRandom(7, keys[rows]))

    batch = run(torch.arange(6))
    assert (batch.hand_pose != init).any()
    shuffled = run(torch.tensor([5, 3, 1, 0, 2, 4]))
    for position, row in enumerate((5, 3, 1, 0, 2, 4)):
        assert torch.equal(shuffled.hand_pose[position], batch.hand_pose[row])
    for row in (0, 4):
        alone = run(torch.tensor([row]))
        assert torch.equal(alone.hand_pose[0], batch.hand_pose[row]) and torch.equal(alone.contact_index[0], batch.contact_index[row])
    # The batch statistic (DexGraspNet's) couples the grasps: the same grasp walks differently alone.
    coupled = dataclasses.replace(config, rmsprop_statistic="batch")
    together = optimize(energy, init, object_index, scale, coupled, torch.Generator().manual_seed(0), random=GraspRandom(7, keys))
    alone = optimize(energy, init[:1], object_index[:1], scale[:1], coupled, torch.Generator().manual_seed(0), random=GraspRandom(7, keys[:1]))
    assert not torch.equal(alone.hand_pose[0], together.hand_pose[0])


def test_grasp_random_streams_are_uniform_and_independent():
    from dexlite_pipeline.optim.grasp_random import GraspRandom

    random = GraspRandom(3, torch.arange(2000))
    draws = random.uniform(1, GraspRandom.SWITCH, 8)
    assert draws.shape == (2000, 8) and 0 <= float(draws.min()) and float(draws.max()) < 1
    assert abs(float(draws.mean()) - 0.5) < 0.01 and abs(float(draws.var()) - 1 / 12) < 0.005
    assert not torch.equal(draws, random.uniform(2, GraspRandom.SWITCH, 8))  # another iteration
    assert not torch.equal(draws, random.uniform(1, GraspRandom.ACCEPT, 8))  # another stream
    assert not torch.equal(draws, GraspRandom(4, torch.arange(2000)).uniform(1, GraspRandom.SWITCH, 8))  # another seed
    assert torch.equal(draws[7:9], GraspRandom(3, torch.tensor([7, 8])).uniform(1, GraspRandom.SWITCH, 8))  # a grasp's own numbers
    weighted = random.weighted(torch.tensor([[0.0, 1.0, 3.0]]).expand(2000, -1), 1, GraspRandom.CONTACT_SEARCH, 4)
    share = torch.bincount(weighted.flatten(), minlength=3).double() / weighted.numel()
    assert share[0] == 0 and abs(float(share[2]) - 0.75) < 0.02


def test_hopeless_grasps_stop_where_they_are_and_the_others_walk_on_unchanged(hand, setup):
    """At a checkpoint, grasps above the E_fc / E_dis limits stop in their kept state and are reported with the
    iteration; with each grasp's own draws and statistic the grasps that go on end exactly as without the stop."""
    import dataclasses

    from dexlite_pipeline.optim.config import HopelessStopConfig
    from dexlite_pipeline.optim.grasp_random import GraspRandom

    energy, hulls = setup
    object_index, scale = _batch(6)
    init = initial_poses(hand, hulls, object_index, scale, InitConfig(distance_m=(0.06, 0.09)), torch.Generator().manual_seed(5))
    config = dataclasses.replace(SHORT, rmsprop_statistic="grasp", final_contact_samples=16, contact_search_every=20, trace_every=1)
    keys = torch.arange(6)

    def run(stop):
        return optimize(energy, init, object_index, scale, dataclasses.replace(config, stop_hopeless=stop), torch.Generator().manual_seed(0),
                        random=GraspRandom(7, keys), snapshot_iterations=(30, 60))

    free = run(HopelessStopConfig())
    assert (free.stopped_at_iteration == 0).all()
    at_30 = free.term_traces["E_fc"][30]  # the kept state's E_fc after iteration 30
    limit = float(at_30.median())  # half of them are above it
    stopped = run(HopelessStopConfig(iterations=(30,), max_e_fc=(limit,), max_e_dis_m=(10.0,)))
    hopeless = at_30 > limit
    assert 0 < int(hopeless.sum()) < 6
    assert torch.equal(stopped.stopped_at_iteration, torch.where(hopeless, 30, 0))
    going_on = ~hopeless
    assert torch.equal(stopped.hand_pose[going_on], free.hand_pose[going_on])
    assert torch.equal(stopped.contact_index[going_on], free.contact_index[going_on])
    # A stopped grasp ends in its pose after iteration 30 (the final contact search may change only its contacts).
    torch.testing.assert_close(stopped.hand_pose[hopeless], free.snapshots[30][hopeless])
    torch.testing.assert_close(stopped.snapshots[60][hopeless], free.snapshots[30][hopeless])
    # Its trace stays where it stopped; the others' traces are those of the free run.
    trace_fc = stopped.term_traces["E_fc"]
    assert torch.equal(trace_fc[31:-1, hopeless], trace_fc[30:31, hopeless].expand(len(trace_fc) - 32, -1))
    assert torch.equal(trace_fc[:, going_on], free.term_traces["E_fc"][:, going_on])


def test_grasps_stopped_as_hopeless_are_not_backed_out_of_the_object(hand, setup):
    """With contact resolution, the grasps that walked to the end are resolved as without the stop, and a stopped one
    ends exactly where it stopped, its depth measured there, though resolution would have moved it."""
    import dataclasses

    from dexlite_pipeline.optim.config import HopelessStopConfig
    from dexlite_pipeline.optim.contact_resolution import penetration_depth_m, resolve_contacts
    from dexlite_pipeline.optim.grasp_random import GraspRandom

    energy, hulls = setup
    object_index, scale = _batch(6)
    init = initial_poses(hand, hulls, object_index, scale, InitConfig(distance_m=(0.06, 0.09)), torch.Generator().manual_seed(5))
    allowed = 1e-4  # nearly any touching finger is moved
    config = dataclasses.replace(SHORT, rmsprop_statistic="grasp", trace_every=1, resolve_penetration_to_m=allowed)

    def run(stop):
        return optimize(energy, init, object_index, scale, dataclasses.replace(config, stop_hopeless=stop), torch.Generator().manual_seed(0),
                        random=GraspRandom(7, torch.arange(6)), snapshot_iterations=(30,))

    free = run(HopelessStopConfig())
    at_30 = free.term_traces["E_fc"][30]
    stopped = run(HopelessStopConfig(iterations=(30,), max_e_fc=(float(at_30.median()),), max_e_dis_m=(10.0,)))
    hopeless = stopped.stopped_at_iteration > 0
    assert 0 < int(hopeless.sum()) < 6
    assert torch.equal(stopped.hand_pose[hopeless], stopped.snapshots[30][hopeless])
    would_move = resolve_contacts(energy, stopped.hand_pose[hopeless], object_index[hopeless], scale[hopeless], allowed)
    assert (would_move.steps > 0).any(), "the test's premise: resolution would move a stopped grasp"
    torch.testing.assert_close(stopped.hand_pose[~hopeless], free.hand_pose[~hopeless])
    depth_mm = penetration_depth_m(energy, stopped.hand_pose, object_index, scale) * 1000
    torch.testing.assert_close(stopped.penetration_mm, depth_mm)


def test_hopeless_stop_config_needs_one_limit_of_each_per_checkpoint():
    from dexlite_pipeline.optim.config import HopelessStopConfig

    with pytest.raises(ValueError, match="one entry per checkpoint"):
        HopelessStopConfig(iterations=(300, 600), max_e_fc=(4.0,), max_e_dis_m=(1.0, 1.0))
    assert HopelessStopConfig(iterations=(300,), max_e_fc=(4.0,), max_e_dis_m=(0.02,)).limits_at(300) == (4.0, 0.02)
    assert HopelessStopConfig(iterations=(300,), max_e_fc=(4.0,), max_e_dis_m=(0.02,)).limits_at(301) is None


def test_a_run_whose_grasps_all_stop_ends_where_they_stopped(hand, setup):
    import dataclasses

    from dexlite_pipeline.optim.config import HopelessStopConfig

    energy, hulls = setup
    object_index, scale = _batch(4)
    init = initial_poses(hand, hulls, object_index, scale, InitConfig(distance_m=(0.06, 0.09)), torch.Generator().manual_seed(5))
    every = HopelessStopConfig(iterations=(20,), max_e_fc=(1e-9,), max_e_dis_m=(1e-9,))  # nothing is within these
    config = dataclasses.replace(SHORT, trace_every=10, stop_hopeless=every)
    result = optimize(energy, init, object_index, scale, config, torch.Generator().manual_seed(0), snapshot_iterations=(20, 60))
    assert (result.stopped_at_iteration == 20).all()
    torch.testing.assert_close(result.snapshots[60], result.snapshots[20])
    assert result.trace.shape == (len(result.trace_iterations), 4) and torch.equal(result.trace[-2], result.trace[2])
