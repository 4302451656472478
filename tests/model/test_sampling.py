"""Associated points of pure synthesis that spread over the object: Dex1B's debiased draw and farthest-point spread."""

import math

import numpy as np
import pytest
import torch

from dexlite_pipeline.model.sampling import SampleConfig, debiased_points, spread_points, synthesize, training_point_counts


def _three_far_points() -> torch.Tensor:
    """One cloud (1, 3, 3) of three points 1 m apart."""
    return torch.tensor([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])


def test_a_drawn_point_weighs_one_over_count_plus_one_afterwards():
    """After the first draw its point weighs 1/2 and the others 1: the second draw repeats it with p = 0.5 / 2.5 = 0.2."""
    generator = torch.Generator().manual_seed(0)
    repeats = [int((lambda p: p[0] == p[1])(debiased_points(_three_far_points(), torch.zeros(2, dtype=torch.long), generator, 0.1)))
               for _ in range(3000)]  # fmt: skip
    assert np.mean(repeats) == pytest.approx(0.2, abs=0.025)


def test_prior_counts_steer_the_first_draw_away_from_used_points():
    """Counts (3, 0, 0): the first point weighs 1/4, the others 1 each: p = 0.25 / 2.25."""
    generator = torch.Generator().manual_seed(1)
    counts = torch.tensor([[3.0, 0.0, 0.0]])
    first = [int(debiased_points(_three_far_points(), torch.zeros(1, dtype=torch.long), generator, 0.1, counts)) for _ in range(3000)]
    assert np.mean(np.asarray(first) == 0) == pytest.approx(0.25 / 2.25, abs=0.02)


def test_a_draw_counts_against_its_whole_region_not_its_point_alone():
    """Two clusters of 50 points 1 m apart; a region of 10 cm covers a cluster: the second draw leaves the first cluster with
    p = 2/3 (uniform: 1/2); with a 1 mm region the count stays on the one point and the second draw is nearly uniform."""
    cluster = torch.rand(50, 3, generator=torch.Generator().manual_seed(2)) * 0.05
    cloud = torch.cat([cluster, cluster + torch.tensor([1.0, 0.0, 0.0])])[None]
    for region, expected in ((0.1, 2 / 3), (0.001, 50 / 99.5)):
        generator = torch.Generator().manual_seed(3)
        switched = []
        for _ in range(2000):
            first, second = debiased_points(cloud, torch.zeros(2, dtype=torch.long), generator, region).tolist()
            switched.append((first < 50) != (second < 50))
        assert np.mean(switched) == pytest.approx(expected, abs=0.03), region


def test_each_cloud_keeps_its_own_counts():
    """Two clouds alike: a draw on cloud 0 does not weigh on cloud 1, whose draw then repeats that index with p = 1/3
    (shared counts would make it 0.2)."""
    clouds = torch.cat([_three_far_points(), _three_far_points()])
    generator = torch.Generator().manual_seed(4)
    same = [int((lambda p: p[0] == p[1])(debiased_points(clouds, torch.tensor([0, 1]), generator, 0.1))) for _ in range(3000)]
    assert np.mean(same) == pytest.approx(1 / 3, abs=0.03)


def test_spread_takes_farthest_points_per_cloud():
    """Points on a line 0..9 m, two clouds' rows interleaved: each grasp takes a point as far as any from its cloud's earlier ones."""
    line = torch.stack([torch.arange(10.0), torch.zeros(10), torch.zeros(10)], dim=1)
    clouds = torch.stack([line, line])
    chosen = spread_points(clouds, torch.tensor([0, 1, 0, 1, 0, 1]), torch.Generator().manual_seed(5))
    for cloud in (0, 1):
        picks = chosen[cloud::2].tolist()
        for k in (1, 2):
            gap = lambda x: min(abs(x - p) for p in picks[:k])  # noqa: E731
            assert gap(picks[k]) == max(gap(x) for x in range(10)) > 0, (cloud, picks)


def test_training_counts_give_each_training_grasp_one_point_per_cloud(small_model_config, random_clouds):
    from dexlite_pipeline.model.network import GraspCVAE

    model = GraspCVAE(small_model_config).eval()
    width = small_model_config.pointnet_widths[-1]
    with torch.no_grad():
        _, per_point = model.pointnet(random_clouds(2, 32))
    codes = 7
    conditions = torch.cat([torch.zeros(codes, width), per_point[0, :codes]], 1)  # local features of cloud 0's first points
    model.set_latent_codes(torch.zeros(codes, 8), torch.zeros(codes, 8), conditions, torch.zeros(codes))
    counts = training_point_counts(model, per_point, chunk=3)
    assert counts.shape == (2, 32) and counts.sum(dim=1).tolist() == [codes, codes]
    assert counts[0, :codes].tolist() == [1.0] * codes  # each training grasp's local feature is that of its own point on cloud 0


@pytest.mark.parametrize("rule", ["debiased", "spread"])
def test_synthesis_with_spread_anchors_decodes_finite_poses_on_distinct_points(rule, small_model_config, tiny_assets):
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.network import GraspCVAE

    model = GraspCVAE(small_model_config).eval()
    clouds = ObjectClouds(tiny_assets)
    object_index, scale = np.zeros(6, np.int64), np.full(6, 0.1, np.float32)
    pose = synthesize(model, clouds, object_index, scale, 64, torch.Generator().manual_seed(0), "standard", 1.0, True, rule)
    assert pose.shape == (6, 28) and torch.isfinite(pose).all()
    # the palms differ: six anchors, not one point decoded six times
    assert len({tuple(np.round(p, 4)) for p in pose[:, :3].numpy()}) == 6


def test_config_rejects_unknown_rules_and_empty_regions():
    with pytest.raises(ValueError, match="anchor_rule"):
        SampleConfig(anchor_rule="everywhere")
    with pytest.raises(ValueError, match="anchor_region_m"):
        SampleConfig(anchor_region_m=0.0)


def test_matched_candidates_are_the_best_matches_nearest_first(small_model_config, random_clouds):
    """A training grasp's local feature is that of point 5 of cloud 0: point 5 is its best match, the others follow by distance."""
    from dexlite_pipeline.model.network import GraspCVAE
    from dexlite_pipeline.model.sampling import matched_points

    model = GraspCVAE(small_model_config).eval()
    width = small_model_config.pointnet_widths[-1]
    with torch.no_grad():
        _, per_point = model.pointnet(random_clouds(1, 32))
    model.set_latent_codes(torch.zeros(1, 8), torch.zeros(1, 8), torch.cat([torch.zeros(1, width), per_point[0, 5:6]], 1), torch.zeros(1))
    matches = matched_points(model, per_point, torch.zeros(1, dtype=torch.long), torch.zeros(1, dtype=torch.long), candidates=4)
    distance = (per_point[0] - per_point[0, 5]).norm(dim=-1)
    assert matches.shape == (1, 4) and int(matches[0, 0]) == 5
    assert distance[matches[0]].tolist() == sorted(distance[matches[0]].tolist()) and distance[matches[0, -1]] <= distance.sort().values[3]
    with pytest.raises(ValueError, match="match_candidates"):
        SampleConfig(match_candidates=0)


def test_debiased_codes_prefer_codes_a_cloud_has_not_drawn():
    """Three equally weighted codes, three draws on one cloud: all different with p = 1 x (2/2.5) x (1/2) = 0.4
    (independent draws: 6/27); a draw on another cloud does not count."""
    from dexlite_pipeline.model.latent_codes import debiased_codes

    generator = torch.Generator().manual_seed(6)
    weights = torch.ones(4, 3)
    distinct, crossed = [], []
    for _ in range(3000):
        pick = debiased_codes(weights, torch.tensor([0, 0, 0, 1]), generator).tolist()
        distinct.append(len(set(pick[:3])) == 3)
        crossed.append(pick[3] == pick[0])
    assert np.mean(distinct) == pytest.approx(0.4, abs=0.03)
    assert np.mean(crossed) == pytest.approx(1 / 3, abs=0.03)


def test_debiased_codes_draw_only_codes_their_cloud_can_reach():
    """Each cloud reaches its own codes (weight > 0) only; within them the first draws are all different."""
    from dexlite_pipeline.model.latent_codes import debiased_codes

    generator = torch.Generator().manual_seed(3)
    weights = torch.zeros(6, 1000)
    weights[:3, [5, 500, 999]] = 1.0  # cloud 0's rows (interleaved with cloud 1's below)
    weights[3:, [7, 8]] = torch.tensor([1.0, 3.0])
    cloud = torch.tensor([0, 0, 0, 1, 1, 1])
    pick = debiased_codes(weights[[0, 3, 1, 4, 2, 5]], cloud[[0, 3, 1, 4, 2, 5]], generator).tolist()
    assert set(pick[0::2]) <= {5, 500, 999} and set(pick[1::2]) <= {7, 8}
    seen = [len(set(debiased_codes(weights[:3], cloud[:3], generator).tolist())) for _ in range(500)]
    assert np.mean([s == 3 for s in seen]) == pytest.approx(0.4, abs=0.06)
    with pytest.raises(ValueError, match="no training code"):
        debiased_codes(torch.zeros(2, 4), torch.tensor([0, 0]), generator)


def _with_codes_on(model, clouds: torch.Tensor) -> None:
    """Give ``model`` one training code per cloud of ``clouds``, encoded there (conditions: global and local feature)."""
    with torch.no_grad():
        global_feature, per_point = model.pointnet(clouds)
    conditions = torch.cat([global_feature, per_point[:, 0]], 1)
    latent = model.config.latent_dim
    model.set_latent_codes(torch.zeros(len(clouds), latent), torch.zeros(len(clouds), latent), conditions, torch.arange(len(clouds)))


def test_matched_yaw_turns_a_turned_training_cloud_back(small_model_config, random_clouds):
    """A training cloud turned by 90° is turned by 270° more (back where its codes were encoded); the cloud itself by 0."""
    from dexlite_pipeline.model.network import GraspCVAE
    from dexlite_pipeline.model.pose import turned_clouds
    from dexlite_pipeline.model.sampling import matched_yaws

    torch.manual_seed(0)
    model = GraspCVAE(small_model_config).eval()
    training = random_clouds(1, 64)
    _with_codes_on(model, training)
    quarter = turned_clouds(training, torch.tensor([math.pi / 2]))
    with torch.no_grad():
        yaws = matched_yaws(model, torch.cat([training, quarter]), candidates=4)
    assert yaws.tolist() == pytest.approx([0.0, 3 * math.pi / 2])


def _link_positions_on_both(model, clouds, yaw_candidates: int):
    """Hand link positions (2, 4 grasps, links, 3) of four grasps sampled on clouds 0 and 1 of ``clouds`` (scale 0.1) with
    the same seed and heading match; the Shadow Hand's kinematics."""
    from dexlite_pipeline.hand import ShadowHand

    scale = np.full(4, 0.1, np.float32)
    with torch.no_grad():
        poses = [synthesize(model, clouds, np.full(4, i, np.int64), scale, 64, torch.Generator().manual_seed(3), "aggregate", 1.0, True,
                            "uniform", yaw_candidates=yaw_candidates) for i in (0, 1)]
    hand = ShadowHand()
    return hand.forward(poses[0]).translation, hand.forward(poses[1]).translation


def test_grasps_of_a_turned_object_are_its_grasps_turned(small_model_config, tiny_assets):
    """With yaw matching, sampling an object turned about z by one of the candidate headings gives the object's grasps
    turned with it (the same draws, the same codes): the model's heading no longer depends on the file's."""
    import dataclasses

    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.network import GraspCVAE
    from dexlite_pipeline.model.pose import vertical_rotation

    torch.manual_seed(1)
    model = GraspCVAE(small_model_config).eval()
    asset = tiny_assets[0]
    turn = vertical_rotation(torch.tensor([math.pi / 2], dtype=torch.float64))[0].numpy()
    turned = dataclasses.replace(asset, object_id="turned", surface_points=(asset.surface_points @ turn.T).astype(np.float32),
                                 surface_normals=(asset.surface_normals @ turn.T).astype(np.float32))
    clouds = ObjectClouds([asset, turned])
    drawn = clouds.draw_fixed(torch.tensor([0]), torch.tensor([0.1]), 64)
    _with_codes_on(model, drawn)
    links, turned_links = _link_positions_on_both(model, clouds, yaw_candidates=4)
    assert torch.allclose(turned_links, links @ torch.as_tensor(turn, dtype=torch.float32).T, atol=1e-4)
    # without matching the turned object's grasps are not the turned ones
    assert not torch.allclose(_link_positions_on_both(model, clouds, yaw_candidates=1)[1], turned_links, atol=1e-3)


def test_a_long_object_turned_off_the_right_angles_gets_its_grasps_turned(small_model_config, tiny_assets):
    """A T-shaped object (a hammer's outline) turned about z by 45°, one of the candidate headings, and prepared again
    (its bounding box centred, which moves it in the table's plane): its grasps are the object's grasps turned and moved
    with it. The turned cloud's box is centred again before the model reads it, so the model sees the cloud it saw at the
    matched heading; without that the cloud stands off centre by a few centimetres and the grasps are others."""
    import dataclasses

    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.network import GraspCVAE
    from dexlite_pipeline.model.pose import box_centred_clouds, vertical_rotation

    box = tiny_assets[0]
    points, normals = np.asarray(box.surface_points, np.float64), np.asarray(box.surface_normals, np.float64)
    handle, head = points * [3.0, 0.6, 0.6], points * [0.6, 2.0, 0.6] + [1.5, 0.0, 0.0]
    t_shape = np.concatenate([handle, head])
    t_shape -= (t_shape.max(axis=0) + t_shape.min(axis=0)) / 2  # prepared: bounding box centred
    turn = vertical_rotation(torch.tensor([math.pi / 4], dtype=torch.float64))[0].numpy()
    turned = t_shape @ turn.T
    moved = (turned.max(axis=0) + turned.min(axis=0)) / 2 * [1.0, 1.0, 0.0]  # the turned object's box centre, then taken off
    assert np.linalg.norm(moved) > 0.1  # a T turned by 45° stands well off its old box centre
    t_normals = np.concatenate([normals, normals])
    asset = dataclasses.replace(box, object_id="t", surface_points=t_shape.astype(np.float32), surface_normals=t_normals.astype(np.float32))
    turned_asset = dataclasses.replace(box, object_id="t-turned", surface_points=(turned - moved).astype(np.float32),
                                       surface_normals=(t_normals @ turn.T).astype(np.float32))
    clouds = ObjectClouds([asset, turned_asset])

    torch.manual_seed(1)
    model = GraspCVAE(small_model_config).eval()
    drawn = clouds.draw_fixed(torch.tensor([0]), torch.tensor([0.1]), 64)
    _with_codes_on(model, box_centred_clouds(drawn)[0])
    links, turned_links = _link_positions_on_both(model, clouds, yaw_candidates=8)
    expected = links @ torch.as_tensor(turn, dtype=torch.float32).T - torch.as_tensor(0.1 * moved, dtype=torch.float32)
    assert torch.allclose(turned_links, expected, atol=1e-4)
