"""Shared fixtures: the hand model (built once per session), a sphere and a box as prepared assets with
grasp-like poses on them (the model and post-optimization tests), one torch thread, and the optional real
DexGraspNet sample.

Tests marked ``real_sample`` read the real sample and are deselected unless
$DEXLITE_DEXGRASPNET_SAMPLE is set (``sample_data``); every other test needs nothing outside
the repository.
"""

from pathlib import Path

import pytest
from sample_data import MARKER, SAMPLE_VARIABLE, dexgraspnet_sample_dir

SPHERE_BOX_IDS = ("box", "sphere")


def pytest_report_header(config):
    sample = dexgraspnet_sample_dir()
    if sample is None:
        return f"{MARKER} tests: deselected (set {SAMPLE_VARIABLE} to a DexGraspNet download to run them)"
    return f"{MARKER} tests: on {sample}"


def pytest_collection_modifyitems(config, items):
    """Deselect the tests on the real sample when no sample is named (they are an optional extra)."""
    unmarked = [item.nodeid for item in items if "dexgraspnet_sample" in getattr(item, "fixturenames", ()) and not item.get_closest_marker(MARKER)]
    if unmarked:
        raise pytest.UsageError(f"tests that read the real DexGraspNet sample must be marked {MARKER}: {', '.join(unmarked)}")
    if dexgraspnet_sample_dir() is not None:
        return
    deselected = [item for item in items if item.get_closest_marker(MARKER)]
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = [item for item in items if not item.get_closest_marker(MARKER)]


@pytest.fixture(scope="session")
def hand():
    from dexlite_pipeline.hand import ShadowHand

    return ShadowHand()


@pytest.fixture
def one_torch_thread():
    """Small tensors run fastest on one thread, and a shared, loaded machine punishes spinning OpenMP workers."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def sphere_box_objects(tmp_path_factory):
    """A sphere and a box as prepared assets (normalized size, coarse SDF grid, 256 surface samples)."""
    import trimesh

    from dexlite_pipeline.objects.build import write_asset
    from dexlite_pipeline.objects.config import AssetBuildSettings

    root = tmp_path_factory.mktemp("objects")
    settings = AssetBuildSettings(sdf_resolution=24, surface_points=256)
    meshes = {"sphere": trimesh.creation.icosphere(subdivisions=2, radius=1 / 1.03), "box": trimesh.creation.box(extents=[1.2, 0.9, 0.7])}
    for object_id in SPHERE_BOX_IDS:
        write_asset(meshes[object_id], object_id, root, settings, {"source": "test"}, convex_pieces=[meshes[object_id]])
    return root


@pytest.fixture(scope="session")
def tiny_assets(sphere_box_objects):
    """The loaded assets of ``sphere_box_objects``: box, then sphere."""
    from dexlite_pipeline.objects.assets import load_asset

    return [load_asset(sphere_box_objects, oid) for oid in SPHERE_BOX_IDS]


@pytest.fixture(scope="session")
def make_grasps():
    """``make_grasps(hand, count, seed)``: grasp-like poses on ``sphere_box_objects``, alternating box and sphere."""
    from demo_grasps import facing_grasps

    return lambda hand, count, seed: facing_grasps(hand, SPHERE_BOX_IDS, count, seed)


@pytest.fixture(scope="session")
def dexgraspnet_sample() -> Path:
    """The real DexGraspNet sample named by $DEXLITE_DEXGRASPNET_SAMPLE (tests marked real_sample only)."""
    sample = dexgraspnet_sample_dir()
    if sample is None or not (sample / "dataset").is_dir():
        pytest.fail(f"{SAMPLE_VARIABLE}={sample}: not a DexGraspNet download (no dataset/ folder)")
    return sample
