"""Where objects come from: the embedded ``pybullet_data`` meshes and the user's folders.

A ``MeshSource`` names one mesh file plus the placement its URDF gives it (scale and
rotation), so that an object stands in the orientation its author intended (the stability
test keeps the file orientation). Object ids are stable, filesystem-safe and unique:
``pb-<name>`` for named pybullet meshes, ``pb-random-NNN`` for the procedural
``random_urdfs``, ``user-<stem>`` for the user's meshes (with a short path hash appended
only when two user files share a stem), ``household-<family>-<NNN>`` for the household
objects the project generates, ``household-<family>-<NNN>-p<k>`` for their perturbed variants
(``objects.household``; their meshes are written as .obj files in metres into a folder of the run,
and their real radius is recorded).
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
import xml.etree.ElementTree as ET
import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dexlite_pipeline.objects.rest_pose import RecordedRest

log = logging.getLogger(__name__)

MESH_SUFFIXES = (".obj", ".stl")

# Named pybullet_data objects: id suffix -> URDF (placement read from it) or bare mesh file.
NAMED_PYBULLET_OBJECTS: dict[str, str] = {
    "duck": "duck_vhacd.urdf",
    "teddy": "teddy_large.urdf",
    "bunny": "bunny.obj",
    "torus": "torus/torus_textured.obj",
    "mug": "objects/mug.urdf",
    "soccerball": "soccerball.urdf",
    "lego": "lego/lego.urdf",
    "jenga": "jenga/jenga.urdf",
    "domino": "domino/domino.urdf",
    "sphere": "sphere_smooth.obj",
    "stone": "stone.obj",
    "cube": "cube.urdf",
    "toy-cube": "toys/cube.obj",
    "toy-cylinder": "toys/cylinder.obj",
    "toy-prism": "toys/prism.obj",
    "toy-shape-sorter": "toys/shape_sorter.obj",
    "toy-concave-box": "toys/concave_box.urdf",
}
RANDOM_URDF_DIR = "random_urdfs"
# Share of ``objects.builtin_count`` taken from the named meshes (the rest are procedural).
NAMED_SHARE = 0.25


class ObjectSourceError(ValueError):
    """A configured object source that cannot be used (e.g. a folder that does not exist)."""


@dataclass(frozen=True)
class MeshSource:
    """One mesh to prepare, with the placement (scale per axis, then rotation) to apply first."""

    object_id: str
    source: str  # pybullet_named, pybullet_random, user, user_heldout, household, household_benchmark, household_shapes_benchmark
    file: str
    scale_xyz: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rotation_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    always_heldout: bool = False
    # The object's real radius (m: largest vertex distance from its bounding-box centre) when
    # the file's units are known to be metres (generated objects); None when unknown.
    real_radius_m: float | None = None
    # Metres per unit of the file's coordinates when known (generated objects, `dexlite grasp --units`): sets the
    # millimetre floor of the prepared-versus-input check; None for files of unknown units.
    metres_per_unit: float | None = None
    # Degrees the placed mesh is turned about its z axis (up on the table) before preparation: a held-out object at a
    # seeded random yaw (``objects.heldout_yaw``), so held-out rates do not depend on the orientation its file had.
    turn_deg: float = 0.0
    # A grasp dataset's recorded resting pose (``objects.dataset_collision`` false, dataset objects only): the object is
    # prepared without collision pieces (no convex decomposition) and stands in this pose instead of being simulated.
    recorded_rest: RecordedRest | None = None


def pybullet_data_dir() -> Path:
    import pybullet_data

    return Path(pybullet_data.getDataPath())


def _floats(text: str | None, default: tuple[float, ...]) -> tuple[float, ...]:
    return tuple(float(v) for v in text.split()) if text else default


def urdf_visual_mesh(urdf_path: Path) -> tuple[Path, tuple[float, float, float], tuple[float, float, float]]:
    """The first visual mesh of a URDF: (mesh file, scale xyz, origin rpy).

    The visual mesh is the detailed one (collision meshes in pybullet_data are often coarse
    V-HACD hulls or primitives). The origin's translation is irrelevant after normalization.
    """
    try:
        root = ET.parse(urdf_path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ObjectSourceError(f"{urdf_path}: cannot read URDF: {exc}") from exc
    for visual in root.iter("visual"):
        mesh = visual.find("geometry/mesh")
        if mesh is None or not mesh.get("filename"):
            continue
        origin = visual.find("origin")
        rpy = _floats(origin.get("rpy") if origin is not None else None, (0.0, 0.0, 0.0))
        scale = _floats(mesh.get("scale"), (1.0, 1.0, 1.0))
        if len(scale) == 1:
            scale = scale * 3
        return urdf_path.parent / mesh.get("filename"), scale, rpy
    raise ObjectSourceError(f"{urdf_path}: URDF has no visual mesh")


def _pybullet_source(object_id: str, source: str, path: Path) -> MeshSource:
    if path.suffix == ".urdf":
        mesh, scale, rpy = urdf_visual_mesh(path)
        return MeshSource(object_id, source, str(mesh), tuple(scale), tuple(rpy))
    return MeshSource(object_id, source, str(path))


def named_pybullet_sources() -> list[MeshSource]:
    """The named pybullet_data objects that ship in the installed package, in id order."""
    root = pybullet_data_dir()
    found = []
    for name, rel in sorted(NAMED_PYBULLET_OBJECTS.items()):
        if (root / rel).is_file():
            found.append(_pybullet_source(f"pb-{name}", "pybullet_named", root / rel))
    return found


def random_pybullet_paths() -> list[Path]:
    """URDFs of the procedural ``random_urdfs/NNN/NNN.urdf`` objects, sorted."""
    root = pybullet_data_dir() / RANDOM_URDF_DIR
    return sorted(p for p in root.glob("*/*.urdf") if p.stem == p.parent.name)


def pybullet_random_source(path: Path) -> MeshSource:
    """The procedural pybullet_data object of ``random_urdfs/NNN/NNN.urdf`` (id ``pb-random-NNN``)."""
    return _pybullet_source(f"pb-random-{path.stem}", "pybullet_random", path)


def builtin_sources(count: int, seed: int) -> list[MeshSource]:
    """``count`` embedded objects chosen by a seeded draw: about a quarter named, the rest procedural."""
    if count <= 0:
        return []
    rng = np.random.default_rng([seed, 0x0B1EC7])
    named = named_pybullet_sources()
    n_named = min(len(named), int(round(count * NAMED_SHARE)))
    chosen = [named[i] for i in sorted(rng.choice(len(named), size=n_named, replace=False))]
    randoms = random_pybullet_paths()
    n_random = min(len(randoms), count - n_named)
    for i in sorted(rng.choice(len(randoms), size=n_random, replace=False)):
        chosen.append(pybullet_random_source(randoms[i]))
    return chosen


def procedural_sources(count: int, first: int = 0) -> list[MeshSource]:
    """Procedural pybullet_data objects (``random_urdfs/NNN``, ids ``pb-random-NNN``) to train on, in number order from the
    ``first``-th, the benchmark split's skipped (never trained on): a campaign batch of procedural shapes takes objects
    ``first`` to ``first + count``, so batches never repeat an object."""
    if count <= 0:
        return []
    held_out = benchmark_object_ids()
    paths = [p for p in random_pybullet_paths() if f"pb-random-{p.stem}" not in held_out]
    if first >= len(paths):
        raise ObjectSourceError(f"objects.procedural_first: {first}, but pybullet_data has {len(paths)} procedural objects outside the benchmark split")
    return [pybullet_random_source(p) for p in paths[first : first + count]]


def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "mesh"


def folder_sources(folders, heldout: bool) -> list[MeshSource]:
    """The .obj/.stl files directly inside each folder (sorted); a missing folder is an error."""
    found = []
    for folder in folders:
        path = Path(folder)
        if not path.exists():
            key = "objects.heldout_mesh_dirs" if heldout else "objects.mesh_dirs"
            raise ObjectSourceError(f"{key}: folder {str(folder)!r} does not exist")
        if not path.is_dir():
            raise ObjectSourceError(f"{folder}: not a folder (objects mesh dirs must be folders of .obj/.stl files)")
        found += user_mesh_sources(sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in MESH_SUFFIXES), heldout)
    return found


def user_mesh_sources(files, heldout: bool = False) -> list[MeshSource]:
    """One source per mesh file, id ``user-<file stem>`` (characters outside [A-Za-z0-9_.-] become ``_``)."""
    source = "user_heldout" if heldout else "user"
    return [MeshSource(f"user-{_safe_name(Path(f).stem)}", source, str(f), always_heldout=heldout) for f in files]


def make_ids_unique(sources: list[MeshSource]) -> list[MeshSource]:
    """Give sources sharing an id a suffix from a hash of their file path (stable, order-free)."""
    counts: dict[str, int] = {}
    for s in sources:
        counts[s.object_id] = counts.get(s.object_id, 0) + 1
    unique = []
    for s in sources:
        if counts[s.object_id] > 1:
            digest = hashlib.sha1(os.path.abspath(s.file).encode()).hexdigest()[:6]
            s = dataclasses.replace(s, object_id=f"{s.object_id}-{digest}")
        unique.append(s)
    return unique


# The benchmark split: embedded objects that every profile holds out, so that every model is
# compared on the same objects (made by workflow/scripts/make_benchmark_split.py).
BENCHMARK_SPLIT_FILE = Path(__file__).with_name("benchmark_split.yaml")


def benchmark_object_list() -> list[str]:
    """Ids of the benchmark split's objects (``BENCHMARK_SPLIT_FILE``), in the split's order."""
    import yaml

    record = yaml.safe_load(BENCHMARK_SPLIT_FILE.read_text()) or {}
    return [str(o) for o in record.get("object_ids") or []]


def benchmark_object_ids() -> frozenset[str]:
    """Ids of the benchmark split's objects, as a set."""
    return frozenset(benchmark_object_list())


def pybullet_random_source_of(object_id: str) -> MeshSource:
    """The procedural pybullet_data object with id ``pb-random-NNN`` (its ``random_urdfs/NNN/NNN.urdf``)."""
    number = object_id.removeprefix("pb-random-")
    path = pybullet_data_dir() / RANDOM_URDF_DIR / number / f"{number}.urdf"
    if not path.is_file():
        raise ObjectSourceError(f"{object_id}: no {path} in the installed pybullet_data")
    return pybullet_random_source(path)


def benchmark_sources(count: int) -> list[MeshSource]:
    """The first ``count`` objects of the benchmark split (procedural pybullet_data objects), always held out."""
    ids = benchmark_object_list()
    if count > len(ids):
        raise ObjectSourceError(f"objects.benchmark_objects: {count} asked, the benchmark split ({BENCHMARK_SPLIT_FILE.name}) has {len(ids)}")
    return [dataclasses.replace(pybullet_random_source_of(object_id), always_heldout=True) for object_id in ids[:count]]


# The household benchmark split: generated household objects that are always held out, never
# trained on (``objects.household_benchmark_objects`` adds the first N of it to a run).
HOUSEHOLD_SPLIT_FILE = Path(__file__).with_name("household_split.yaml")
# Folder of a prepared-objects directory where the generated household meshes are written.
HOUSEHOLD_MESH_DIR = "household_meshes"


def household_benchmark_list() -> list[str]:
    """Ids of the household benchmark split's objects (``HOUSEHOLD_SPLIT_FILE``), in the split's order."""
    import yaml

    record = yaml.safe_load(HOUSEHOLD_SPLIT_FILE.read_text()) or {}
    return [str(o) for o in record.get("object_ids") or []]


# The shapes split: instances of the shape families and perturbed instances of every family, always held out, never
# trained on (``objects.shapes_benchmark_objects`` adds the first N of it to a run).
SHAPES_SPLIT_FILE = Path(__file__).with_name("shapes_split.yaml")


def shapes_benchmark_list() -> list[str]:
    """Ids of the shapes split's objects (``SHAPES_SPLIT_FILE``), in the split's order."""
    import yaml

    record = yaml.safe_load(SHAPES_SPLIT_FILE.read_text()) or {}
    return [str(o) for o in record.get("object_ids") or []]


def held_out_household_ids() -> frozenset[str]:
    """Every id of the household and shapes splits: training draws skip these and every variant of their instances."""
    return frozenset(household_benchmark_list()) | frozenset(shapes_benchmark_list())


def household_sources(training_count: int, benchmark_count: int, folder, training_first: int = 0,
                      families: tuple[str, ...] = (), variants: tuple[int, ...] = (0,), shapes_count: int = 0) -> list[MeshSource]:
    """Generated household objects: ``training_count`` training ones from the ``training_first``-th on (round-robin
    over ``families``, the original twelve when empty, each instance in the perturbation ``variants`` given; never an
    object of the household or shapes split, nor a variant of one), the first ``benchmark_count`` of the household split
    and the first ``shapes_count`` of the shapes split (both always held out). Their meshes (metres) are written to
    ``folder`` as ``<id>.obj``; other ``household-*.obj`` files there (from an earlier, larger run) are removed.
    """
    from dexlite_pipeline.objects.household import household_object, training_household_ids, write_mesh_obj

    if training_count <= 0 and benchmark_count <= 0 and shapes_count <= 0:
        return []
    split, shapes = household_benchmark_list(), shapes_benchmark_list()
    if benchmark_count > len(split):
        raise ObjectSourceError(f"objects.household_benchmark_objects: {benchmark_count} asked, the household split ({HOUSEHOLD_SPLIT_FILE.name}) has {len(split)}")
    if shapes_count > len(shapes):
        raise ObjectSourceError(f"objects.shapes_benchmark_objects: {shapes_count} asked, the shapes split ({SHAPES_SPLIT_FILE.name}) has {len(shapes)}")
    if not variants or any(v < 0 for v in variants) or len(set(variants)) != len(variants):
        raise ObjectSourceError(f"objects.household_variants: must be distinct numbers >= 0 (0: as generated), not {list(variants)}")
    if folder is None:
        raise ObjectSourceError("objects.household_count / household_benchmark_objects / shapes_benchmark_objects: no folder given to write the generated meshes to")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        training = (training_household_ids(training_first + training_count, held_out_household_ids(), families, tuple(variants))[training_first:]
                    if training_count > 0 else [])
    except ValueError as error:
        raise ObjectSourceError(f"objects.household_families: {error}") from None
    wanted = [(i, "household", False) for i in training]
    wanted += [(i, "household_benchmark", True) for i in split[:benchmark_count]]
    wanted += [(i, "household_shapes_benchmark", True) for i in shapes[:shapes_count]]
    sources = []
    for object_id, kind, heldout in wanted:
        generated = household_object(object_id)
        path = folder / f"{object_id}.obj"
        write_mesh_obj(generated.mesh, path)
        sources.append(MeshSource(object_id, kind, str(path), always_heldout=heldout, real_radius_m=generated.real_radius_m,
                                  metres_per_unit=1.0))
    keep = {Path(s.file).name for s in sources}
    for stale in folder.glob("household-*.obj"):
        if stale.name not in keep:
            stale.unlink()
    return sources


def rebuilt_source_of(object_id: str, folder) -> MeshSource:
    """The source of an object a run prepared from pybullet_data (``pb-random-NNN``) or the household generator
    (``household-<family>-NNN[-p<k>]``, its mesh written to ``folder``): what rebuilds it from its id alone."""
    from dexlite_pipeline.objects.household import household_object, parse_household_id, write_mesh_obj

    if object_id.startswith("pb-random-"):
        return pybullet_random_source_of(object_id)
    try:
        parse_household_id(object_id)
    except ValueError:
        raise ObjectSourceError(f"{object_id}: neither a pybullet_data object (pb-random-NNN) nor a household one (household-<family>-NNN[-p<k>])") from None
    generated = household_object(object_id)
    path = Path(folder) / f"{object_id}.obj"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_mesh_obj(generated.mesh, path)
    kind = ("household_benchmark" if object_id in household_benchmark_list() else
            "household_shapes_benchmark" if object_id in shapes_benchmark_list() else "household")
    return MeshSource(object_id, kind, str(path), real_radius_m=generated.real_radius_m, metres_per_unit=1.0)


def collect_sources(
    builtin_count: int,
    mesh_dirs,
    heldout_mesh_dirs,
    seed: int,
    benchmark_heldout: bool = False,
    benchmark_objects: int = 0,
    household_count: int = 0,
    household_benchmark_objects: int = 0,
    household_dir=None,
    household_first: int = 0,
    household_families: tuple[str, ...] = (),
    household_variants: tuple[int, ...] = (0,),
    shapes_benchmark_objects: int = 0,
    rebuilt_training_ids: tuple[str, ...] = (),
    procedural_count: int = 0,
    procedural_first: int = 0,
    rebuilt_rests: dict[str, RecordedRest] | None = None,
) -> list[MeshSource]:
    """Every object to prepare: embedded default, generated household objects, user folders, always-held-out folders.

    ``benchmark_heldout``: embedded objects of the benchmark split are always held out.
    ``benchmark_objects``: the first this many objects of the benchmark split are added (held
    out), so that a small run is also measured on objects that no model ever trains on.
    ``household_count`` / ``household_benchmark_objects``: generated household objects for
    training (from the ``household_first``-th on, of ``household_families`` or every family) / from the household
    split (held out), their meshes written to ``household_dir``; ``household_variants``: the perturbation variants drawn
    of each training instance; ``shapes_benchmark_objects``: the first this many of the shapes split (held out).
    ``procedural_count`` / ``procedural_first``: procedural pybullet_data objects for training in number order
    (``procedural_sources``), beside those ``builtin_count`` draws. ``rebuilt_rests``: resting poses by id of
    ``rebuilt_training_ids`` (``objects.dataset_collision`` false): each such object is prepared without collision
    pieces and stands in its recorded pose (``MeshSource.recorded_rest``).
    """
    # A file listed twice (a folder repeated, or in both lists) is one object; held out wins.
    user: dict[str, MeshSource] = {}
    for s in folder_sources(mesh_dirs, heldout=False) + folder_sources(heldout_mesh_dirs, heldout=True):
        user[os.path.realpath(s.file)] = s
    builtin = builtin_sources(builtin_count, seed)
    if benchmark_heldout:
        benchmark = benchmark_object_ids()
        builtin = [dataclasses.replace(s, always_heldout=True) if s.object_id in benchmark else s for s in builtin]
    drawn = {s.object_id for s in builtin}
    builtin += [s for s in procedural_sources(procedural_count, procedural_first) if s.object_id not in drawn]
    drawn = {s.object_id for s in builtin}
    builtin += [s for s in benchmark_sources(benchmark_objects) if s.object_id not in drawn]
    household = household_sources(household_count, household_benchmark_objects, household_dir, household_first, household_families,
                                  household_variants, shapes_benchmark_objects)
    rebuilt = rebuilt_training_sources(rebuilt_training_ids, {s.object_id for s in builtin + household}, household_dir)
    if rebuilt_rests:
        rebuilt = [dataclasses.replace(s, recorded_rest=rebuilt_rests[s.object_id]) if s.object_id in rebuilt_rests else s for s in rebuilt]
    return make_ids_unique(builtin + household + rebuilt + list(user.values()))


def rebuilt_training_sources(object_ids, drawn: set[str], folder) -> list[MeshSource]:
    """Training sources rebuilt from their ids alone (a grasp dataset's objects: ``objects.dataset_objects``), in the
    order given, skipping the ids already ``drawn`` by the other sources. An id of a held-out split (the benchmark,
    household or shapes split), or one that nothing rebuilds, is left out with a warning naming it: a dataset holds
    training objects only, so either means a dataset made against other splits or by hand."""
    from dexlite_pipeline.objects.household import base_household_id

    held_out = held_out_household_ids() | benchmark_object_ids()
    sources = []
    for object_id in object_ids:
        if object_id in drawn:
            continue
        if object_id in held_out:
            log.warning("dataset object %s left out: it is in a held-out split, never trained on", object_id)
            continue
        try:
            base = base_household_id(object_id) if object_id.startswith("household-") else object_id
        except ValueError:
            base = object_id
        if base in held_out:
            log.warning("dataset object %s left out: a variant of %s, which is in a held-out split", object_id, base)
            continue
        if household_dir_needed(object_id) and folder is None:
            raise ObjectSourceError("objects.dataset_objects: no folder given to write the rebuilt household meshes to")
        try:
            sources.append(rebuilt_source_of(object_id, folder))
        except ObjectSourceError as error:
            log.warning("dataset object left out: %s", error)
        drawn.add(object_id)
    return sources


def household_dir_needed(object_id: str) -> bool:
    """Whether rebuilding ``object_id`` writes a generated mesh (household objects) rather than reading pybullet_data."""
    return object_id.startswith("household-")
