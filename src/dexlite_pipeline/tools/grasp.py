"""Grasps that hold for the user's own meshes, in one call: ``dexlite grasp MESH [MESH ...] --out DIR``.

Steps (each logs its progress):

1. prepare every mesh (repair, normalization, convex pieces, SDF) into ``DIR/objects``;
   a mesh that cannot be used is listed with its reason, the others go on;
2. synthesize ``n`` grasps per object: with a trained model (``cvae.pt``), CVAE samples
   refined by post-optimization (config sections ``sample`` and ``post_optimize``);
   without one, energy optimization from scratch (section ``seed_grasps``, the pipeline's
   seed synthesis). Object scale: the configured scales (normalized object radius about
   8-12 cm), or with ``real_size`` the mesh's own size, its units read as metres;
3. lift test and six-direction test of every grasp with the ``lift`` section's constants
   (the pipeline's physics, unchanged);
4. write ``DIR/grasps.zarr`` (the grasps that lift the object, same schema as the
   pipeline's stores, with the six-direction results per grasp), ``DIR/all_grasps.zarr``
   (every grasp with its failure reason), ``DIR/dexgraspnet/`` (DexGraspNet layout of the
   held grasps and meshes), ``DIR/renders/*.png`` and ``DIR/summary.md``.

Settings come from the checkout's ``config.yaml`` when the package runs from a checkout
(as ``install.sh`` installs it), overlaid by the caller's sections; the physics constants
of the lift test are never changed here.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexlite_pipeline.config import from_section, validate_config
from dexlite_pipeline.sharding import shard_generator

log = logging.getLogger("dexlite.grasp")

DEFAULT_GRASPS_PER_OBJECT = 32
DEFAULT_RENDERS_PER_OBJECT = 2
CHECKOUT_CONFIG = Path(__file__).resolve().parents[3] / "config.yaml"
STEPS = 5


class GraspToolError(ValueError):
    """Input the tool cannot work with (no mesh files, every mesh rejected, a bad model file)."""


@dataclass
class GraspRequest:
    """What to grasp and how: mesh files or folders, output folder, budget and options."""

    meshes: list[str]
    out_dir: str
    grasps_per_object: int = DEFAULT_GRASPS_PER_OBJECT
    real_size: bool = False
    device: str | None = None  # None: the config's device
    model: str | None = None  # trained cvae.pt: sample + post-optimize; None: optimization from scratch
    config: dict = field(default_factory=dict)  # config sections over the defaults
    threads: int = 1
    renders_per_object: int = DEFAULT_RENDERS_PER_OBJECT


@dataclass
class GraspOutcome:
    """Counts per object and where the outputs are."""

    objects: list[dict]
    rejected: list[dict]
    held: int
    total: int
    seconds: float
    summary_path: Path


def default_config() -> dict:
    """The checkout's config.yaml (validated) when present, else {} (the dataclass defaults)."""
    import yaml

    if not CHECKOUT_CONFIG.is_file():
        log.warning("no config.yaml beside the package (%s): using the built-in defaults", CHECKOUT_CONFIG)
        return {}
    return validate_config(yaml.safe_load(CHECKOUT_CONFIG.read_text()) or {}, str(CHECKOUT_CONFIG))


def merge_config(base: dict, overlay: dict) -> dict:
    """``overlay`` merged into ``base`` key by key (nested mappings merged, anything else replaced)."""
    out = dict(base)
    for key, value in overlay.items():
        out[key] = merge_config(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def mesh_sources(paths: list[str]):
    """One ``MeshSource`` per mesh file given, or per .obj/.stl file directly inside a folder given."""
    from dexlite_pipeline.objects.sources import MESH_SUFFIXES, MeshSource, _make_ids_unique, _safe_name

    files: list[Path] = []
    for text in paths:
        path = Path(text)
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in MESH_SUFFIXES)
            if not found:
                raise GraspToolError(f"{text}: folder has no {'/'.join(MESH_SUFFIXES)} files")
            files += found
        elif path.is_file():
            if path.suffix.lower() not in MESH_SUFFIXES:
                raise GraspToolError(f"{text}: not a mesh file (expected {' or '.join(MESH_SUFFIXES)})")
            files.append(path)
        else:
            raise GraspToolError(f"{text}: no such file or folder")
    unique = list(dict.fromkeys(p.resolve() for p in files))
    return _make_ids_unique([MeshSource(f"user-{_safe_name(p.stem)}", "user", str(p)) for p in unique])


def _step(number: int, text: str, *args) -> None:
    log.info(f"[{number}/{STEPS}] {text}", *args)


def object_scales(assets, real_size: bool, configured: tuple[float, ...]) -> dict[str, tuple[float, ...]]:
    """Scales per object: the configured ones, or the mesh's own size (1 / normalization factor, in metres)."""
    if not real_size:
        return {a.object_id: tuple(configured) for a in assets}
    scales = {}
    for asset in assets:
        factor = float(asset.meta.get("normalization_factor", math.nan))
        if not math.isfinite(factor) or factor <= 0:
            raise GraspToolError(f"{asset.object_id}: asset has no normalization factor; cannot keep its real size")
        scales[asset.object_id] = (1.0 / factor,)
    return scales


def _balanced_rows(per_scale: int, scale_count: int, wanted: int) -> np.ndarray:
    """Rows of a scale-major block (``per_scale`` grasps per scale) taking ``wanted``, the scales in turn."""
    k = np.arange(per_scale * scale_count)
    order = np.lexsort((k // per_scale, k % per_scale))
    return np.sort(order[:wanted])


def synthesize_from_scratch(assets, scales: dict, n: int, config: dict, device, seed: int):
    """``n`` grasps per object by energy optimization from convex-hull starts (section ``seed_grasps``)."""
    from dexlite_pipeline.energy.grasp_energy import EnergyConfig
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.optim.seed import SeedConfig, synthesize

    base = from_section(SeedConfig, config.get("seed_grasps"), "config.seed_grasps")
    energy_config = from_section(EnergyConfig, config.get("energy"), "config.energy")
    generator = shard_generator("seed_grasps", seed, 0)
    parts = []
    for number, asset in enumerate(assets, start=1):
        object_scales = scales[asset.object_id]
        per_scale = -(-n // len(object_scales))
        seed_config = dataclasses.replace(base, grasps_per_object=per_scale, scales=object_scales)
        log.info("object %d/%d %s: optimizing %d grasps, %d iterations", number, len(assets), asset.object_id,
                 per_scale * len(object_scales), seed_config.annealing.iterations)
        grasps, _ = synthesize([asset], seed_config, energy_config, generator, device)
        parts.append(grasps.select(_balanced_rows(per_scale, len(object_scales), n)))
    grasps = GraspSet.concatenate(parts)
    grasps.arrays["method"] = np.full(len(grasps), "seed", dtype=object)
    return grasps


def synthesize_with_model(assets, scales: dict, n: int, config: dict, model_path: str, device, seed: int):
    """``n`` CVAE samples per object, refined by post-optimization (sections ``sample``, ``post_optimize``)."""
    import torch

    from dexlite_pipeline.energy.grasp_energy import EnergyConfig, GraspEnergy
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.io.grasp_store import GraspSet
    from dexlite_pipeline.model.checkpoint import cloud_reading, load_checkpoint
    from dexlite_pipeline.model.data import ObjectClouds
    from dexlite_pipeline.model.post_optimization import PostOptimizeConfig, refine
    from dexlite_pipeline.model.sampling import SampleConfig, synthesize

    sample_config = from_section(SampleConfig, config.get("sample"), "config.sample")
    post_config = from_section(PostOptimizeConfig, config.get("post_optimize"), "config.post_optimize")
    margin = from_section(EnergyConfig, config.get("energy"), "config.energy").self_penetration_margin_m
    try:
        model, checkpoint = load_checkpoint(model_path, device)
    except ValueError as exc:
        raise GraspToolError(str(exc)) from None
    points, fixed = cloud_reading(checkpoint, sample_config.points_per_cloud)
    clouds = ObjectClouds(assets, device)
    object_index = np.repeat(np.arange(len(assets)), n)
    scale = np.concatenate([np.resize(np.asarray(scales[a.object_id], np.float32), n) for a in assets])
    trained = sorted(float(s) for s in sample_config.scales)  # the training grasps' scales
    outside = sorted({round(float(s), 4) for s in scale if not min(trained) * 0.8 <= s <= max(trained) * 1.25})
    if outside:
        log.warning("scales %s are far from the training scales %s: expect fewer grasps that hold", outside, trained)
    generator = shard_generator("grasp_tool_post_optimize", seed, 0)
    log.info("sampling %d grasps from %s", len(object_index), model_path)
    prior, anchor_rule = sample_config.latent_prior, sample_config.anchor_rule
    if len(model.codes_mu) == 0 or len(model.codes_condition) == 0:  # a model saved without its training codes
        log.warning("%s holds no training codes: sampling from N(0, I) at uniform points instead of %s / %s", model_path, prior, anchor_rule)
        prior, anchor_rule = "standard", "uniform"
    poses = synthesize(
        model, clouds, object_index, scale, points, generator, prior, sample_config.latent_temperature, fixed, anchor_rule,
        sample_config.neighbour_clouds, sample_config.anchor_region_m, sample_config.debias_training, sample_config.match_candidates,
        sample_config.debias_codes,
    )
    hand = ShadowHand(device)
    energy = GraspEnergy.from_assets(
        hand, assets, EnergyConfig(weights=post_config.energy_weights, object_points=post_config.energy_object_points, self_penetration_margin_m=margin)
    )
    log.info("post-optimizing %d grasps, %d iterations", len(object_index), post_config.annealing.iterations)
    refined = refine(
        energy, poses, torch.as_tensor(object_index, device=device), torch.as_tensor(scale, device=device), post_config, generator, "surface"
    )
    arrays = {k: v for k, v in refined.arrays.items() if not k.startswith("trace_") and k != "energy_trace"}
    arrays["object_id"] = np.asarray([assets[i].object_id for i in object_index], dtype=object)
    arrays["scale"] = scale
    arrays["method"] = np.full(len(object_index), "cvae_post", dtype=object)
    return GraspSet(arrays)


def render_examples(grasps, objects_dir: Path, out_dir: Path, per_object: int) -> list[Path]:
    """Up to ``per_object`` held grasps per object as PNGs, six-direction passes first (one failure when none held)."""
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.report.render import render_grasp_png

    hand, written = ShadowHand(), []
    held = np.asarray(grasps.arrays["lift_success"], bool)
    six = np.asarray(grasps.arrays.get("six_dir_success", np.zeros(len(grasps), bool)), bool)
    for object_id in sorted(set(grasps.object_id.tolist())):
        rows = np.flatnonzero((grasps.object_id == object_id) & held)
        rows = rows[np.argsort(~six[rows], kind="stable")][:per_object]  # those that also pass the six-direction test first
        if not len(rows):
            finite = np.flatnonzero((grasps.object_id == object_id) & np.isfinite(grasps.hand_pose).all(axis=1))
            rows = finite[:1]
        for row in rows:
            if held[row]:
                outcome = "HELD: lifted, six-direction " + ("passed" if six[row] else "failed")
            else:
                outcome = f"NOT HELD: {grasps.arrays['failure_reason'][row] or 'dropped'}"
            path = out_dir / f"{object_id}_{row:04d}.png"
            title = f"{object_id}  grasp {row}  scale {float(grasps.scale[row]):.3f} m\n{outcome}"
            render_grasp_png(hand, grasps.hand_pose[row], object_id, float(grasps.scale[row]), [str(objects_dir)], out=path, title=title)
            written.append(path)
    return written


def per_object_rows(grasps, sources, catalog) -> list[dict]:
    """One summary row per prepared object: counts and shares of grasps that held."""
    rows = []
    file_of = {s.object_id: s.file for s in sources}
    for object_id in sorted(catalog.loc[catalog["status"] == "ok", "object_id"]):
        mask = grasps.object_id == object_id
        total = int(mask.sum())
        lift = np.asarray(grasps.arrays["lift_success"], bool)[mask]
        six = np.asarray(grasps.arrays["six_dir_success"], bool)[mask]
        scales = sorted({round(float(s), 4) for s in grasps.scale[mask]})
        rows.append({
            "object_id": object_id, "file": file_of.get(object_id, ""), "scales_m": scales, "grasps": total,
            "lift": int(lift.sum()), "six_dir": int(six.sum()), "both": int((lift & six).sum()),
        })  # fmt: skip
    return rows


def _share(count: int, total: int) -> str:
    return f"{count}/{total} ({100 * count / total:.0f}%)" if total else "0/0"


def summary_markdown(
    request: GraspRequest, rows: list[dict], rejected: list[dict], method: str, step_seconds: dict, renders: list[Path], lift_config
) -> str:
    """The one-page ``summary.md``: objects, counts, lift and six-direction shares side by side, time."""
    total = sum(r["grasps"] for r in rows)
    lift, six, both = (sum(r[k] for r in rows) for k in ("lift", "six_dir", "both"))
    seconds = sum(step_seconds.values())
    lines = [
        "# Grasps",
        "",
        f"**{_share(lift, total)} grasps held the object in the lift test; {_share(both, total)} also passed the "
        f"six-direction test** ({len(rows)} object(s), {method}, {seconds / 60:.1f} min).",
        "",
        f"A grasp *holds* when the hand lifts the object {lift_config.lift_height_m:g} m and keeps at least "
        f"{100 * lift_config.success_lift_ratio:.0f}% of that rise (MuJoCo, object {lift_config.object_mass_kg:g} kg, "
        f"friction {lift_config.friction:g}); the six-direction test pushes the held object with "
        f"{lift_config.six_dir_force_per_kg_n:g} N/kg along ±x, ±y, ±z (gravity off) and passes when it moves less than "
        f"{100 * lift_config.six_dir_max_translation_m:g} cm and turns less than {lift_config.six_dir_max_rotation_deg:g}° each time. "
        "`grasps.zarr` and `dexgraspnet/` hold the grasps that held in the lift test.",
        "",
        "| object | file | scale (m) | grasps | lift test held | six-direction held | both |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        scales = ", ".join(f"{s:.3f}" for s in r["scales_m"])
        lines.append(f"| {r['object_id']} | {Path(r['file']).name} | {scales} | {r['grasps']} | {_share(r['lift'], r['grasps'])} | "
                     f"{_share(r['six_dir'], r['grasps'])} | {_share(r['both'], r['grasps'])} |")
    lines.append(f"| **all** | | | {total} | {_share(lift, total)} | {_share(six, total)} | {_share(both, total)} |")
    if rejected:
        lines += ["", "## Meshes that could not be used", ""]
        lines += [f"- `{r['file']}`: {r['reason']}" for r in rejected]
    if renders:
        lines += ["", "## Examples", ""]
        lines += [f"![{p.stem}](renders/{p.name})" for p in renders]
    lines += ["", "## Run", "", "| step | seconds |", "| --- | ---: |"]
    lines += [f"| {name} | {value:.0f} |" for name, value in step_seconds.items()]
    lines += [
        "",
        f"Grasps per object: {request.grasps_per_object}; size: {'the mesh’s own (metres)' if request.real_size else 'configured scales'}; "
        f"model: {request.model or 'none (optimization from scratch)'}.",
        "",
    ]
    return "\n".join(lines)


def run_grasp_tool(request: GraspRequest) -> GraspOutcome:
    """Prepare, synthesize, test and write everything for ``request`` (see the module docstring)."""
    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.io.atomic import write_text_atomic
    from dexlite_pipeline.io.dexgraspnet import export_dexgraspnet
    from dexlite_pipeline.io.grasp_store import write_grasp_store
    from dexlite_pipeline.objects.assets import load_asset
    from dexlite_pipeline.objects.prepare import ObjectsConfig, prepare_objects
    from dexlite_pipeline.optim.seed import SeedConfig
    from dexlite_pipeline.sim.config import lift_config_from
    from dexlite_pipeline.sim.results import lift_grasp_set

    if request.grasps_per_object < 1:
        raise GraspToolError(f"--n must be at least 1, got {request.grasps_per_object}")
    started = time.perf_counter()
    config = merge_config(default_config(), request.config)
    config["objects"] = {**config.get("objects", {}), "builtin_count": 0, "mesh_dirs": [], "heldout_mesh_dirs": []}  # only the given meshes
    validate_config(config, "configuration", partial=True)
    seed = int(config.get("seed", 0))
    device = resolve_device(request.device or config.get("device") or "auto")
    out_dir = Path(request.out_dir)
    objects_dir = out_dir / "objects"
    sources = mesh_sources(request.meshes)
    times: dict[str, float] = {}

    _step(1, "preparing %d mesh(es) into %s", len(sources), objects_dir)
    t = time.perf_counter()
    objects_config = from_section(ObjectsConfig, config["objects"], "config.objects")
    catalog = prepare_objects(sources, objects_dir, objects_config, seed, max(1, request.threads))
    times["prepare"] = time.perf_counter() - t
    rejected = [{"file": r.file, "reason": r.reason} for r in catalog[catalog["status"] != "ok"].itertuples()]
    for r in rejected:
        log.warning("mesh not usable: %s: %s", r["file"], r["reason"])
    ok_ids = sorted(catalog.loc[catalog["status"] == "ok", "object_id"])
    if not ok_ids:
        raise GraspToolError(f"none of the {len(sources)} mesh(es) could be prepared: " + "; ".join(f"{r['file']}: {r['reason']}" for r in rejected))
    assets = [load_asset(objects_dir, oid) for oid in ok_ids]

    method = f"CVAE samples + post-optimization ({request.model})" if request.model else "energy optimization from scratch"
    configured = (
        from_section(SeedConfig, config.get("seed_grasps"), "config.seed_grasps").scales
        if not request.model
        else tuple((config.get("sample") or {}).get("scales") or SeedConfig().scales)
    )
    scales = object_scales(assets, request.real_size, configured)
    _step(2, "synthesizing %d grasps for each of %d object(s): %s, device %s", request.grasps_per_object, len(assets), method, device)
    t = time.perf_counter()
    if request.model:
        grasps = synthesize_with_model(assets, scales, request.grasps_per_object, config, request.model, device, seed)
    else:
        grasps = synthesize_from_scratch(assets, scales, request.grasps_per_object, config, device, seed)
    times["synthesize"] = time.perf_counter() - t

    _step(3, "lift test and six-direction test of %d grasps on %d thread(s)", len(grasps), request.threads)
    t = time.perf_counter()
    lift_config = lift_config_from(config, six_directions=True)
    tested, _ = lift_grasp_set(grasps, [str(objects_dir)], lift_config, max(1, request.threads))
    times["lift and six-direction tests"] = time.perf_counter() - t

    _step(4, "writing grasp stores and the DexGraspNet export")
    t = time.perf_counter()
    held_mask = np.asarray(tested.arrays["lift_success"], bool)
    held = tested.select(held_mask)
    attrs = {"stage": "grasp", "method": method, "config": config, "real_size": request.real_size, "meshes": [s.file for s in sources]}
    write_grasp_store(out_dir / "all_grasps.zarr", tested, attrs)
    write_grasp_store(out_dir / "grasps.zarr", held, {**attrs, "selection": "lift_success"})
    if len(held):
        export_dexgraspnet(held, out_dir / "dexgraspnet", [str(objects_dir)])
    times["write"] = time.perf_counter() - t

    _step(5, "rendering examples and writing the summary")
    t = time.perf_counter()
    renders = render_examples(tested, objects_dir, out_dir / "renders", request.renders_per_object) if request.renders_per_object > 0 else []
    times["render"] = time.perf_counter() - t
    rows = per_object_rows(tested, sources, catalog)
    summary_path = out_dir / "summary.md"
    write_text_atomic(summary_path, summary_markdown(request, rows, rejected, method, times, renders, lift_config))
    seconds = time.perf_counter() - started
    for r in rows:
        log.info("%s: lift test held %s, six-direction %s, both %s", r["object_id"], _share(r["lift"], r["grasps"]),
                 _share(r["six_dir"], r["grasps"]), _share(r["both"], r["grasps"]))
    return GraspOutcome(objects=rows, rejected=rejected, held=int(held_mask.sum()), total=len(tested), seconds=seconds, summary_path=summary_path)

