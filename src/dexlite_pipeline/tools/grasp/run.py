"""``dexlite grasp``'s run, phase by phase: check the request, prepare the meshes, synthesize and lift-test the
first grasps, top up the objects short of distinct held grasps, select and write the stores, render and summarize.
Each phase logs its progress step; its wall-clock seconds go into the run's ``RunRecord`` (the summary's "Run" table)."""

from __future__ import annotations

import dataclasses
import logging
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dexlite_pipeline.tools.grasp.checks import CheckedRequest, check_request
from dexlite_pipeline.tools.grasp.outputs import render_examples, store_attrs, write_grasp_stores, write_view
from dexlite_pipeline.tools.grasp.request import SOURCE_MODEL, SOURCE_OPTIMIZATION, GraspOutcome, GraspRequest, GraspToolError
from dexlite_pipeline.tools.grasp.selection import distinct_labels, kept_rows
from dexlite_pipeline.tools.grasp.summary import (
    next_steps, per_object_rows, per_source_counts, per_type_counts, preparation_text, share_text, summary_markdown,
)  # fmt: skip
from dexlite_pipeline.tools.grasp.synthesis import (
    concatenate_sources, object_scales, objects_to_top_up, starts_per_scale, synthesize_from_scratch, synthesize_with_model, top_up_seed,
    top_up_until_distinct,
)

if TYPE_CHECKING:
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.objects.assets import ObjectAsset
    from dexlite_pipeline.sim.config import LiftConfig
    from dexlite_pipeline.tabletop import SupportPlanes

log = logging.getLogger("dexlite.grasp")

STEPS = 5  # progress steps of a run without the top-up (one more with it)
TESTING = "lift test and six-direction test of %d grasps on %d thread(s)"


@dataclass
class RunRecord:
    """Wall-clock seconds of each phase of one run, and how many top-up batches it made (each over every short object)."""

    prepare_seconds: float = 0.0
    synthesize_seconds: float = 0.0
    lift_test_seconds: float = 0.0
    top_up_batches: int = 0
    top_up_synthesize_seconds: float = 0.0  # over all top-up batches
    top_up_lift_test_seconds: float = 0.0  # over all top-up batches
    select_and_write_seconds: float = 0.0
    render_seconds: float = 0.0
    view_seconds: float = 0.0
    coverage_seconds: float = 0.0

    def step_seconds(self) -> dict[str, float]:
        """Step name -> seconds in run order, as the summary's "Run" table lists them (the top-up's rows only when it made a batch)."""
        top_up = {
            "top-up: synthesize": self.top_up_synthesize_seconds, "top-up: lift and six-direction tests": self.top_up_lift_test_seconds,
        } if self.top_up_batches else {}  # fmt: skip
        return {
            "prepare": self.prepare_seconds, "synthesize": self.synthesize_seconds, "lift and six-direction tests": self.lift_test_seconds,
            **top_up, "distinct grasps and writing": self.select_and_write_seconds, "render": self.render_seconds,
            "3-D view": self.view_seconds, "surface coverage": self.coverage_seconds,
        }  # fmt: skip


@dataclass
class PreparedObjects:
    """The meshes prepared for grasping and the scene they stand in."""

    objects_dir: Path
    object_ids: list[str]  # the prepared objects, sorted
    assets: list[ObjectAsset]  # one per prepared object, in ``object_ids`` order
    rejected: list[dict]  # meshes not tried (the hand cannot hold them) or not prepared: file, reason, kind
    support_planes: SupportPlanes | None  # each object's table; None: floating objects
    support: dict[str, str]  # object id -> the pose it stands in, in words (recorded in the stores)


@dataclass
class GraspRun:
    """One run's checked request, prepared objects and record, and how it makes and lift-tests batches of grasps."""

    request: GraspRequest
    checked: CheckedRequest
    prepared: PreparedObjects
    out_dir: Path
    steps: int  # progress steps: ``STEPS``, one more with the top-up
    record: RunRecord
    lift_config: LiftConfig = field(init=False)  # the config's lift test with the six-direction test on

    def __post_init__(self) -> None:
        self.lift_config = dataclasses.replace(self.checked.config.lift, six_directions=True)

    def from_scratch(self, chosen: list[ObjectAsset], seed: int, n: int | None = None, type_plans: dict[str, np.ndarray] | None = None) -> GraspSet:
        """``n`` grasps (default: the request's) per chosen object by optimization from scratch: ``--from-scratch`` and the
        top-up alike; ``type_plans``: each object's start types (``type_rounds``) instead of the configured shares."""
        config = self.checked.config
        return synthesize_from_scratch(chosen, object_scales(chosen, self.request, config.optimize_grasps.scales),
                                       n or self.request.grasps_per_object, config, self.checked.device, seed, self.prepared.support_planes,
                                       self.checked.hand, type_plans)  # fmt: skip

    def from_scratch_tested(self, chosen: list[ObjectAsset], seed: int) -> GraspSet:
        """``--from-scratch``: the request's grasps per chosen object optimized and lift-tested, in ``type_rounds`` rounds
        (``tools.grasp.type_rounds``; one round: the configured shares). Adds the seconds to the record's steps."""
        from dexlite_pipeline.tools.grasp.type_rounds import optimize_in_rounds

        config = self.checked.config
        scales = object_scales(chosen, self.request, config.optimize_grasps.scales)

        def optimize(n: int, round_seed: int, plans: dict[str, np.ndarray] | None) -> GraspSet:
            t = time.perf_counter()
            grasps = self.from_scratch(chosen, round_seed, n, plans)
            self.record.synthesize_seconds += time.perf_counter() - t
            return grasps

        rounds_tested = []

        def test(grasps: GraspSet) -> GraspSet:
            if rounds_tested:
                log.info("type round %d of %d: " + TESTING, len(rounds_tested) + 1, self.request.type_rounds, len(grasps), self.request.threads)
            else:
                _step(3, self.steps, TESTING, len(grasps), self.request.threads)
            rounds_tested.append(len(grasps))
            t = time.perf_counter()
            tested = self.lift_tested(grasps, SOURCE_OPTIMIZATION)
            self.record.lift_test_seconds += time.perf_counter() - t
            return tested

        return optimize_in_rounds(chosen, self.request.grasps_per_object, self.request.type_rounds, config.optimize_grasps.grasp_types.shares(),
                                  seed, lambda n: starts_per_scale(n, [scales[a.object_id] for a in chosen]), optimize, test,
                                  concatenate_sources)  # fmt: skip

    def with_model(self) -> GraspSet:
        """``n`` CVAE samples per object refined by post-optimization."""
        config, assets = self.checked.config, self.prepared.assets
        return synthesize_with_model(assets, object_scales(assets, self.request, config.sample.scales), self.request.grasps_per_object, config,
                                     self.checked.loaded_model, self.request.model, self.checked.device, config.seed,
                                     self.prepared.support_planes, self.checked.loaded_evaluator, self.checked.hand)  # fmt: skip

    def lift_tested(self, grasps: GraspSet, source: str) -> GraspSet:
        """The grasps with their lift and six-direction test results and their ``source``."""
        from dexlite_pipeline.sim.results import lift_grasp_set

        tested, _ = lift_grasp_set(grasps, [str(self.prepared.objects_dir)], self.lift_config, self.request.threads,
                                   support_planes=self.prepared.support_planes, known_failures=hopeless_optimizations(grasps),
                                   hand=self.checked.hand)  # fmt: skip
        tested.arrays["source"] = np.full(len(tested), source, dtype=object)
        return tested

    def top_up_batch(self, chosen: list[ObjectAsset], batch: int) -> GraspSet:
        """Top-up batch ``batch`` (0-based) for the chosen objects: optimized from scratch with its own seed, then lift-tested."""
        t = time.perf_counter()
        grasps = self.from_scratch(chosen, top_up_seed(self.checked.config.seed, batch))
        self.record.top_up_synthesize_seconds += time.perf_counter() - t
        self.record.top_up_batches += 1
        log.info("top-up batch %d: " + TESTING, batch + 1, len(grasps), self.request.threads)
        t = time.perf_counter()
        tested = self.lift_tested(grasps, SOURCE_OPTIMIZATION)
        self.record.top_up_lift_test_seconds += time.perf_counter() - t
        return tested


def hopeless_optimizations(grasps: GraspSet) -> np.ndarray | None:
    """Per grasp, why it is known to fail without a test ('' to test it): an optimization from scratch or a
    post-optimization of a sample stopped early as hopeless (``optimize_grasps.stop_hopeless``: about 1 in 70 such
    grasps holds, against 1 in 2 of the others; ``post_optimize.stop_hopeless``: it was not backed out of the object).
    The model's refined samples (``method`` cvae_post) name the post-optimization."""
    stopped = grasps.arrays.get("stopped_at_iteration")
    if stopped is None:
        return None
    method = np.asarray(grasps.arrays.get("method", np.full(len(grasps), "optimization", dtype=object))).astype(str)
    return np.asarray([("post-optimization of the sample" if m == "cvae_post" else "optimization") + " stopped early (hopeless)" if s > 0 else ""
                       for s, m in zip(np.asarray(stopped), method)], dtype=object)  # fmt: skip


def hand_note(record: dict) -> str:
    """The summary's line on the hand: none for the Shadow Hand; another hand's name and joints, and how it is drawn."""
    if not record or record.get("hand", "shadow") == "shadow":
        return ""
    return (f"Hand: {record['hand']} ({len(record['joint_names'])} joints; poses are 6 + {len(record['joint_names'])} numbers, the "
            "joints named in the stores' `joint_names`). The pictures and the 3-D view draw its collision shapes.")


def _step(number: int, steps: int, text: str, *args) -> None:
    log.info(f"[{number}/{steps}] {text}", *args)


def with_top_up(request: GraspRequest) -> bool:
    """Whether the run tops up the model's grasps: with a model and ``min_distinct`` > 0."""
    return bool(request.model) and request.min_distinct > 0


def clear_earlier_output(out_dir: Path, overwrite: bool) -> None:
    """With ``overwrite``, delete an earlier run's output folder (checked to be one before)."""
    if overwrite and out_dir.is_dir() and any(out_dir.iterdir()):
        log.info("--overwrite: clearing the earlier run's output in %s", out_dir)
        shutil.rmtree(out_dir)


def prepare_meshes(request: GraspRequest, checked: CheckedRequest, objects_dir: Path, steps: int, record: RunRecord) -> PreparedObjects:
    """Step 1: every mesh the hand may hold, prepared into ``objects_dir`` (one that cannot be is listed with its reason),
    and the table each prepared object stands on. None prepared is a ``GraspToolError``."""
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.objects.prepare import prepare_objects
    from dexlite_pipeline.tabletop import tool_support_planes

    config = checked.config
    skipped = {r["file"] for r in checked.not_tried}
    sources = [s for s in checked.sources if s.file not in skipped]
    for r in checked.not_tried:
        log.warning("not tried: %s: %s", r["file"], r["reason"])
    _step(1, steps, "preparing %d mesh(es) into %s", len(sources), objects_dir)
    t = time.perf_counter()
    catalog = prepare_objects(sources, objects_dir, config.objects, config.seed, request.threads)
    record.prepare_seconds = time.perf_counter() - t
    failed = [{"file": r.file, "reason": r.reason, "kind": "prepare"} for r in catalog[catalog["status"] != "ok"].itertuples()]
    ok_ids = sorted(catalog.loc[catalog["status"] == "ok", "object_id"])
    rejected = checked.not_tried + failed
    if not ok_ids:
        raise GraspToolError(f"none of the {len(checked.sources)} mesh(es) could be used: " + "; ".join(f"{r['file']}: {r['reason']}" for r in rejected))
    for r in failed:
        log.warning("mesh not usable: %s: %s", r["file"], r["reason"])
    log.info("prepared %d of %d mesh(es)", len(ok_ids), len(checked.sources))
    assets = [load_asset(objects_dir, oid) for oid in ok_ids]
    # tabletop: each object's table (None: floating)
    planes, support = tool_support_planes(assets, config.scene.table, request.upright_axis, config.stability, config.seed)
    return PreparedObjects(objects_dir, ok_ids, assets, rejected, planes, support)


def first_grasps(run: GraspRun) -> tuple[GraspSet, str]:
    """Steps 2 and 3: ``n`` grasps per object from the model (without one, by optimization from scratch), lift-tested.
    Returns the tested grasps and the method in words."""
    request, checked, record = run.request, run.checked, run.record
    if request.model:
        method = f"CVAE samples + post-optimization ({request.model})"
        if request.evaluator:
            method = (f"CVAE samples ranked by a learned evaluator ({request.evaluator}: the best distinct {request.grasps_per_object} of "
                      f"{request.grasps_per_object * checked.config.evaluator.pool_factor} per object) + post-optimization ({request.model})")
        _step(2, run.steps, "synthesizing %d grasps for each of %d object(s): %s, device %s", request.grasps_per_object, len(run.prepared.assets),
              method, checked.device)  # fmt: skip
    else:
        method = "energy optimization from scratch"
        _step(2, run.steps, "optimizing %d grasps for each of %d object(s) from scratch, device %s", request.grasps_per_object,
              len(run.prepared.assets), checked.device)  # fmt: skip
    if not request.model:
        if request.type_rounds > 1:
            method += f" in {request.type_rounds} rounds, the later ones dealt to the grasp types that held on each object"
        return run.from_scratch_tested(run.prepared.assets, checked.config.seed), method
    t = time.perf_counter()
    grasps = run.with_model()
    record.synthesize_seconds = time.perf_counter() - t
    _step(3, run.steps, TESTING, len(grasps), request.threads)
    t = time.perf_counter()
    tested = run.lift_tested(grasps, SOURCE_MODEL)
    record.lift_test_seconds = time.perf_counter() - t
    return tested, method


def top_up_short_objects(run: GraspRun, tested: GraspSet) -> tuple[GraspSet, list[str]]:
    """Step 4: batches of optimization from scratch for each object with fewer than ``min_distinct`` distinct held
    grasps (``top_up_until_distinct``). Returns every grasp so far and the ids of the objects topped up."""
    request, checked, assets = run.request, run.checked, run.prepared.assets
    short = objects_to_top_up(assets, tested, distinct_labels(tested, checked.config), request.min_distinct)
    if short:
        _step(4, run.steps, "top-up: the model gave fewer than %d distinct held grasps (--min-distinct) for %d of %d object(s) (%s): "
              "optimizing batches of %d grasps from scratch until each has %d (at most %d batches), device %s", request.min_distinct,
              len(short), len(assets), ", ".join(a.object_id for a in short), request.grasps_per_object, request.min_distinct,
              request.top_up_batches, checked.device)  # fmt: skip
    else:
        _step(4, run.steps, "no top-up: the model gave at least %d distinct held grasps (--min-distinct) for every object", request.min_distinct)
    tested, topped_up, short = top_up_until_distinct(assets, tested, checked.config, request.min_distinct, request.top_up_batches, run.top_up_batch)
    if short:
        log.warning("top-up: after %d batch(es) still fewer than %d distinct held grasps for %s", request.top_up_batches,
                    request.min_distinct, ", ".join(a.object_id for a in short))  # fmt: skip
    return tested, topped_up


def select_and_write(run: GraspRun, tested: GraspSet, method: str, topped_up: list[str]) -> tuple[np.ndarray, GraspSet]:
    """Next to last step: label the distinct held grasps (``tested`` gets its ``distinct_label`` array), keep the
    best of each (or every held grasp without ``distinct``) and write the stores and the DexGraspNet export.
    Returns the labels and the kept grasps."""
    _step(run.steps - 1, run.steps, "distinct grasps, grasp stores and the DexGraspNet export")
    request, checked, prepared = run.request, run.checked, run.prepared
    t = time.perf_counter()
    labels = distinct_labels(tested, checked.config)
    tested.arrays["distinct_label"] = labels
    kept = tested.select(kept_rows(tested, labels, request.distinct))
    attrs = {**store_attrs(request, checked.mapping, [s.file for s in checked.sources], method, prepared.support, topped_up),
             **checked.hand_record}
    write_grasp_stores(run.out_dir, tested, kept, attrs, request.distinct, prepared.objects_dir)
    run.record.select_and_write_seconds = time.perf_counter() - t
    return labels, kept


def render_and_summarize(
    run: GraspRun, tested: GraspSet, labels: np.ndarray, kept: GraspSet, method: str, topped_up: list[str]
) -> tuple[list[dict], Path]:
    """Last step: pictures, the 3-D view, each object's surface touched, and ``summary.md``. Returns the summary's
    rows (one per prepared object) and the summary's path."""
    from dexlite_pipeline.atomic import write_text_atomic
    from dexlite_pipeline.evaluation.metrics import per_object_diversity
    from dexlite_pipeline.evaluation.protocol import coverage_arrays
    from dexlite_pipeline.hand.described import is_described

    _step(run.steps, run.steps, "rendering examples and writing the summary")
    request, checked, prepared, record = run.request, run.checked, run.prepared, run.record
    config, objects_dir = checked.config, prepared.objects_dir
    drawn = checked.hand if is_described(checked.hand) else None  # None: the Shadow Hand's own visual meshes
    t = time.perf_counter()
    per_object = request.renders_per_object
    renders = render_examples(tested, labels, objects_dir, run.out_dir / "renders", per_object, drawn) if per_object > 0 else []
    record.render_seconds = time.perf_counter() - t
    t = time.perf_counter()
    view = write_view(run.out_dir, kept, objects_dir, method, drawn)
    record.view_seconds = time.perf_counter() - t
    t = time.perf_counter()
    touched = coverage_arrays(tested, [str(objects_dir)], config.diversity, hand=checked.hand)
    diversity_rows = per_object_diversity({**tested.arrays, **touched}, labels >= 0, config.diversity)
    record.coverage_seconds = time.perf_counter() - t
    coverage = {object_id: row["coverage"] for object_id, row in diversity_rows.items()}
    rows = per_object_rows(tested, labels, checked.sources, checked.sizes, prepared.object_ids, coverage)
    by_source, by_type = per_source_counts(tested, config), per_type_counts(tested, config)
    preparation = {asset.object_id: asset.meta for asset in prepared.assets}
    for r in rows:
        r["by_source"], r["topped_up"] = by_source.get(r["object_id"], {}), r["object_id"] in topped_up
        r["by_type"] = by_type.get(r["object_id"], {})
        r["prepared_as"] = preparation_text(preparation[r["object_id"]])
    summary_path = run.out_dir / "summary.md"
    write_text_atomic(summary_path, summary_markdown(request, rows, prepared.rejected, method, record.step_seconds(), renders, run.lift_config,
                                                     config.diversity, len(kept), view, hand_note(checked.hand_record)))  # fmt: skip
    return rows, summary_path


def run_grasp_tool(request: GraspRequest) -> GraspOutcome:
    """Check, prepare, synthesize, test and write everything for ``request`` (see the package docstring)."""
    checked = check_request(request)
    started = time.perf_counter()
    out_dir = Path(request.out_dir)
    clear_earlier_output(out_dir, request.overwrite)
    record, steps = RunRecord(), STEPS + with_top_up(request)
    run = GraspRun(request, checked, prepare_meshes(request, checked, out_dir / "objects", steps, record), out_dir, steps, record)
    tested, method = first_grasps(run)
    topped_up: list[str] = []
    if with_top_up(request):
        tested, topped_up = top_up_short_objects(run, tested)
        if topped_up:
            method += f", topped up by energy optimization from scratch on {len(topped_up)} of {len(run.prepared.assets)} object(s)"
    labels, kept = select_and_write(run, tested, method, topped_up)
    rows, summary_path = render_and_summarize(run, tested, labels, kept, method, topped_up)
    seconds = time.perf_counter() - started
    for r in rows:
        reasons = ", ".join(f"{k} {v}" for k, v in r["failures"].items()) or "none"
        log.info("%s: held %s, %d distinct; failures: %s", r["object_id"], share_text(r["lift"], r["grasps"]), r["distinct"], reasons)
    rejected = run.prepared.rejected
    return GraspOutcome(objects=rows, rejected=rejected, held=int((labels >= 0).sum()), distinct=sum(r["distinct"] for r in rows),
                        total=len(tested), seconds=seconds, summary_path=summary_path, next_steps=next_steps(request, rows, rejected),
                        topped_up=topped_up)  # fmt: skip
