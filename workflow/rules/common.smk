# Shared helpers for the rules: config validation, per-stage params, code hashes, input
# files read from outside results/, threads, shard lists, the prepared-object folders and
# repeatable options of the stages' command lines.
#
# Rerun contract: a rule's params hold (1) the config sections it uses, as canonical JSON
# (stage_params), and (2) a hash of its stage code and everything that code imports from
# the package (code_hash); stages that read files from outside results/ (meshes, a DexGraspNet
# download) list them as inputs. Snakemake's default rerun triggers (mtime, params, input,
# code, software-env) then rerun exactly the stage whose settings, code or input files
# changed, and what depends on its outputs. Threads: each rule's default is set here for a
# plain `snakemake --cores N` (heavy unsharded stages all N, sharded stages one per job);
# the profiles (profiles/local, profiles/slurm) may override them and hold the other resources.
import json
import os
import shlex
import sys
from pathlib import Path

from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

# The package source beside this Snakefile is the last place the imports below look: a
# Snakemake installed without the package (e.g. for `--sdm conda`, whose environment is built
# only after parsing) still parses the workflow, while an installed package or a PYTHONPATH
# entry is used first. Parse-time code stays light (standard library and PyYAML only).
sys.path.append(str(Path(workflow.basedir) / "src"))

from dexlite_pipeline.codehash import code_hash as _package_code_hash
from dexlite_pipeline.config import SCHEMA_PATH, result_neutral_keys, retired_keys_message, section_json
from dexlite_pipeline.settings import SHADOW, PipelineConfig, hand_setting_problem

# A renamed or removed key (config.RETIRED_KEYS) fails with its replacement, before the schema's bare unknown-key error.
if retired := retired_keys_message(config):
    raise WorkflowError(retired)
validate(config, str(SCHEMA_PATH))
# Config key hand: a known name or an existing file, checked while parsing (the file's MJCF is read by the first stage
# that makes the hand, which refuses it in one line). Every stage takes the hand (optimize_grasps to evaluate, the data
# loop, the report, dataset_grasps, model_batch); prepare_objects and stability_filter do not depend on it. The Shadow
# Hand's stages are given no hand (stage_params), so a default run's params are what they were before hands.
HAND = str(config.get("hand", SHADOW))
if problem := hand_setting_problem(HAND):
    raise WorkflowError(problem)
# DexGraspNet's grasps are the Shadow Hand's, which curation would refuse to mix with another's (a grasp dataset, dataset.root,
# holds one hand's grasps: dataset_grasps refuses one of another hand in one line).
if HAND != SHADOW and config.get("dexgraspnet", {}).get("root"):
    raise WorkflowError(f"hand: {HAND}: dexgraspnet.root holds the Shadow Hand's grasps; leave it empty with another hand")

RESULTS = "results"
LOGS = "logs"
SHARDS = [f"{i:03d}" for i in range(int(config["shards"]))]
# Rounds of the data loop (workflow/rules/loop.smk; 0 = none: the workflow without it).
LOOP_ROUNDS = int(config["loop"]["rounds"])
# Threads of a sharded stage's job: one, so that `--cores` shards run side by side.
SHARD_THREADS = 1
# The conda environment every rule declares; used only with `--sdm conda` (see README).
# Its post-deploy script installs the checkout named by DEXLITE_SOURCE: this one.
CONDA_ENV = str(Path(workflow.basedir) / "envs" / "dexlite.yaml")
os.environ.setdefault("DEXLITE_SOURCE", str(workflow.basedir))
# Config keys that cannot change any output reach their stage but never rerun it: section ->
# its keys marked setting(result_neutral=True) in the settings classes. Today log cadence
# (optimize_grasps.progress_every) and the batch size of energy evaluation (curate. and
# evaluate.energy_batch_size: energies are computed grasp by grasp; batches of 1, 37, 256 and
# 1000 gave bit-identical results on CPU). The optimizers' batch sizes (optimize_grasps.batch_size,
# post_optimize.batch_size) do change results (their step uses the batch-mean squared gradient)
# and stay tracked.
RESULT_NEUTRAL_KEYS = result_neutral_keys(PipelineConfig)
# Files the object loader reads from objects.mesh_dirs / heldout_mesh_dirs: those directly in
# each folder with one of these suffixes, in any case (objects.sources.folder_sources; that
# module needs numpy, so it is not imported at parse time: tests/workflow/test_input_reruns.py
# checks that both list the same files).
MESH_SUFFIXES = (".obj", ".stl")


wildcard_constraints:
    shard=r"\d{3}",


def all_cores():
    """Threads for a stage that uses every core it is given: the total of `--cores` on one
    machine. Where no total exists (cluster executors, `--unlock`) this is 1 and the
    profile's `set-threads` decides."""
    try:
        return workflow.cores
    except WorkflowError:
        return 1


class StageConfigJSON(str):
    """The JSON a stage is given, whose repr (what Snakemake records to detect changed params)
    is the JSON without RESULT_NEUTRAL_KEYS (``tracked``): changing one of those reruns nothing."""

    def __repr__(self):
        return repr(self.tracked)


def stage_params(*sections, source=None, told_hand=True):
    """Canonical JSON of the config sections a stage uses: changes rerun exactly that stage.

    ``source`` is the config to take them from (default: the whole config; the evaluation
    steps pass a cut-down one). Given as a params function: Snakemake rebuilds a plain-string
    param as a plain str (wildcards applied), which would lose StageConfigJSON's tracked form.
    ``told_hand``: with a hand other than the Shadow Hand, a stage is given section "hand" (it takes the hand from there);
    False for the stages whose outputs do not depend on the hand (prepare_objects, stability_filter).
    """
    source = config if source is None else source
    if told_hand and HAND != SHADOW and "hand" not in sections:  # the Shadow Hand's stages are given none: their params as before
        source, sections = {**source, "hand": HAND}, (*sections, "hand")
    tracked_config = {
        name: {k: v for k, v in section.items() if k not in RESULT_NEUTRAL_KEYS.get(name, ())}
        if isinstance(section, dict) else section
        for name, section in source.items()
    }
    stage_json = StageConfigJSON(section_json(source, *sections))
    stage_json.tracked = section_json(tracked_config, *sections)
    return lambda wildcards: stage_json


def code_hash(*modules):
    """Hash of the code a stage runs: rerun the stage when it (or anything it imports) changes.

    Names are stage modules ("prepare_objects" means dexlite_pipeline.stages.prepare_objects)
    or full dotted module names.
    """
    return _package_code_hash(*(m if "." in m else f"dexlite_pipeline.stages.{m}" for m in modules))


def checkout_file(relative):
    """A file of this checkout (``relative`` to the Snakefile's folder) as a rule's input path.

    Relative to the working directory when the checkout is the working directory or inside it (a
    plain `snakemake` in the checkout), so that a finished run whose folder is moved or copied (a
    renamed checkout, a cluster filesystem mounted elsewhere) names the same inputs and plans
    nothing; absolute when the run directory is elsewhere (`--directory`), which then does not
    depend on where that directory is."""
    path = Path(workflow.basedir) / relative
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def mesh_dir_files(wildcards):
    """The mesh files of objects.mesh_dirs and heldout_mesh_dirs, as the object loader picks
    them: a new file changes prepare_objects' input set and an edited one is newer than its
    outputs, so either reruns it. A missing folder lists nothing (the stage names it)."""
    objects = config["objects"]
    files = []
    for folder in map(Path, [*objects["mesh_dirs"], *objects["heldout_mesh_dirs"]]):
        if folder.is_dir():
            files += sorted(str(p) for p in folder.iterdir() if p.is_file() and p.suffix.lower() in MESH_SUFFIXES)
    return list(dict.fromkeys(files))


def dexgraspnet_files(wildcards):
    """The files the DexGraspNet import reads (io.dexgraspnet's layout): ROOT/dataset/*.npy
    and, where present, each one's ROOT/meshdata/<code>/coacd/decomposed.obj."""
    root = Path(config["dexgraspnet"]["root"])
    grasp_files = sorted((root / "dataset").glob("*.npy"))
    meshes = [root / "meshdata" / path.stem / "coacd" / "decomposed.obj" for path in grasp_files]
    return [str(path) for path in [*grasp_files, *meshes] if path.is_file()]


def dataset_root():
    """The grasp dataset of dataset.root as a path for rule inputs ("" when not used): relative to the checkout unless absolute."""
    root = config["dataset"]["root"]
    if not root:
        return ""
    return root if Path(root).is_absolute() else checkout_file(root)


def dataset_files(wildcards=None):
    """The dataset's files (tables and grasp batches): inputs, so an added batch reruns what reads it."""
    root = dataset_root()
    if not root:
        return []
    if not (Path(root) / "batches.csv").is_file():
        raise WorkflowError(f"dataset.root: {root} is not a grasp dataset (no batches.csv; dexlite dataset-add makes one)")
    return [str(Path(root) / name) for name in ("batches.csv", "objects.csv")] + sorted(str(p) for p in (Path(root) / "grasps").glob("*.npz"))


def dataset_object_tables(wildcards=None):
    """With objects.dataset_objects: the dataset's tables that list its objects (an added batch reprepares), else none."""
    if not config["objects"].get("dataset_objects"):
        return []
    if not dataset_root():
        raise WorkflowError("objects.dataset_objects: dataset.root is empty (no grasp dataset to take the objects of)")
    return dataset_files()[:2]


def model_batch_generator_files(wildcards=None):
    """The model and evaluator files section model_batch names (the package's for the run's hand when "shipped"):
    inputs, so a re-shipped or retrained model reruns the batch."""
    from dexlite_pipeline.settings import build_config
    from dexlite_pipeline.tools.model_batch import ModelBatchError, generator_files

    try:
        typed = build_config(config)
        model, evaluator = generator_files(typed.model_batch, typed.hand)
    except ModelBatchError as error:
        raise WorkflowError(str(error)) from None
    return [str(model)] + ([str(evaluator)] if evaluator else [])


def model_batch_outputs():
    """The shards of a model-made dataset batch (config/profiles/household_model_batch.yaml)."""
    return expand(f"{RESULTS}/model_batch/shard_{{shard}}.zarr", shard=SHARDS)


def trains_on_dataset_only():
    """Whether every training object comes from the grasp dataset (objects.dataset_objects and no other source of
    training objects): the run then optimizes and lift-tests held-out objects only, which no learning stage reads."""
    objects = config["objects"]
    other_sources = (objects["builtin_count"], objects.get("procedural_count", 0), objects.get("household_count", 0),
                     objects["mesh_dirs"], config["dexgraspnet"]["root"])
    return bool(dataset_root() and objects.get("dataset_objects")) and not any(other_sources)


def training_grasp_stores():
    """The stores the learning stages take known grasps from: the lift-validation shards and, with dataset.root, the
    dataset's shards (dataset_grasps), both of every shard; the dataset's alone when it gives every training object
    (the learning stages then do not wait for the held-out objects' optimization)."""
    stores = [] if trains_on_dataset_only() else expand(f"{RESULTS}/lift/shard_{{shard}}.zarr", shard=SHARDS)
    if dataset_root():
        stores += expand(f"{RESULTS}/dataset/shard_{{shard}}.zarr", shard=SHARDS)
    return stores


def learning_objects_dirs():
    """Prepared-object folders the stages after curation read (plus the DexGraspNet import's when configured)."""
    dirs = [f"{RESULTS}/objects"]
    if config["dexgraspnet"]["root"]:
        dirs.append(f"{RESULTS}/dexgraspnet/objects")
    return dirs


def learning_cli_options(option, paths):
    """``--option path`` for each of ``paths``: a repeatable option of a stage's command line."""
    return " ".join(f"--{option} {p}" for p in paths)


def round_model(round_number):
    """The model of data-loop round ``round_number``: round 0's is train_cvae's, round r's loop_train's."""
    return f"{RESULTS}/model/cvae.pt" if int(round_number) == 0 else f"{RESULTS}/round_{int(round_number)}/model/cvae.pt"


def final_model():
    """The model the evaluation's cvae_* rows sample from: the last round's (train_cvae's without the loop)."""
    return round_model(LOOP_ROUNDS)


def final_outputs():
    """The final products: object catalog, stability table, curation summary, lift-validated
    shards, the trained model, post-optimized shards (with the random-init baseline), the
    evaluation (metrics, per-object table, report) and, with the data loop, its table."""
    return [
        f"{RESULTS}/objects/catalog.parquet",
        f"{RESULTS}/stability/stability.parquet",
        f"{RESULTS}/curate/summary.csv",
        *[f"{RESULTS}/lift/shard_{shard}.zarr" for shard in SHARDS],
        f"{RESULTS}/model/cvae.pt",
        f"{RESULTS}/model/history.csv",
        f"{RESULTS}/model/training_curves.png",
        *[f"{RESULTS}/post/{prefix}_{shard}.zarr" for prefix in ("shard", "random_shard") for shard in SHARDS],
        f"{RESULTS}/eval/metrics.csv",
        f"{RESULTS}/eval/per_object.csv",
        f"{RESULTS}/eval/report.html",
        *([f"{RESULTS}/loop.csv"] if LOOP_ROUNDS else []),
    ]


def default_outputs(wildcards=None):
    """The default target's inputs: ``final_outputs()`` (every stage they need takes config key hand)."""
    return final_outputs()


def stale_temporaries(root):
    """Temporary siblings (`.NAME.tmp-XXXXXXXX`) that a killed job left behind under ``root``."""
    root = Path(root)
    return sorted(root.rglob(".*.tmp-*")) if root.is_dir() else []


onstart:
    # A job killed hard (SIGKILL, node failure) cannot remove its temporary output; such
    # leftovers are never outputs (outputs are renamed into place whole), so drop them.
    import shutil

    for leftover in stale_temporaries(RESULTS):
        if leftover.is_dir():
            shutil.rmtree(leftover, ignore_errors=True)
        else:
            leftover.unlink(missing_ok=True)
