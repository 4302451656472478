"""``dexlite grasp MESH [MESH ...] --out DIR``: grasps that hold for your own meshes, in one command.

Prepares the meshes (a folder of .obj/.stl files works too) at their real size (``--units``),
synthesizes grasps (with the shipped model, package data, its samples ranked by the shipped grasp
evaluator where one ships, topped up by optimization from scratch for each object where the model
gives fewer than ``--min-distinct`` distinct held grasps; by optimization from scratch only with
``--from-scratch``), keeps the distinct ones that pass the lift test and writes ``DIR/grasps.zarr``,
``DIR/dexgraspnet/``, ``DIR/renders/`` and ``DIR/summary.md`` (``dexlite_pipeline.tools.grasp``). On a table (``scene.table``, the default) each mesh stands in its stable pose, or with
``--upright-axis`` up; the log says which. Exit status 0 when some grasp held, 1 when none did
(the outputs are written all the same), 2 for unusable input (one line, before any work).
"""

from __future__ import annotations

import argparse
import logging

log = logging.getLogger("dexlite.grasp")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from dexlite_pipeline.model.config import GRASP_TYPE_NAMES
    from dexlite_pipeline.tabletop import UPRIGHT_AXES
    from dexlite_pipeline.tools.grasp import (
        DEFAULT_GRASPS_PER_OBJECT, DEFAULT_MIN_DISTINCT, DEFAULT_RENDERS_PER_OBJECT, DEFAULT_TOP_UP_BATCHES, UNIT_METRES,
    )

    parser.add_argument("meshes", nargs="+", help=".obj/.stl mesh files, or folders of them")
    parser.add_argument("--out", required=True, help="output folder (new or empty; an earlier run's only with --overwrite)")
    parser.add_argument("--n", type=int, default=DEFAULT_GRASPS_PER_OBJECT, help="grasps synthesized per object (default %(default)s)")
    parser.add_argument("--units", choices=list(UNIT_METRES), default=None,
                        help="length unit of the mesh files (default m); objects are grasped at their real size")
    parser.add_argument("--resize-to-training", action="store_true",
                        help="grasp each object resized to the training radii (config sample.scales or optimize_grasps.scales: 8, 10, 12 cm) instead of its real size")
    parser.add_argument("--distinct", action=argparse.BooleanOptionalAction, default=True,
                        help="keep one grasp of each near-duplicate group in grasps.zarr (default: on)")
    parser.add_argument("--overwrite", action="store_true", help="clear an earlier run's --out folder first")
    parser.add_argument("--device", default=None, help="auto, cpu, cuda or cuda:N (default: the config's device)")
    parser.add_argument("--model", default=None, help="trained model (cvae.pt) to sample and post-optimize with (default: the shipped "
                        "model, dexlite_pipeline/data/shadow-hand-household/cvae.pt)")
    parser.add_argument("--evaluator", default=None, metavar="FILE",
                        help="a learned grasp evaluator (evaluator.pt) that ranks the model's samples: it draws evaluator.pool_factor "
                        "times --n samples per object and keeps the --n best-scored distinct ones before post-optimization (default: "
                        "the shipped evaluator with the shipped model, none with --model)")
    parser.add_argument("--no-evaluator", action="store_true", help="do not rank the model's samples (the first --n samples per object)")
    parser.add_argument("--min-distinct", type=int, default=None, metavar="N",
                        help="with a model: an object whose model grasps give fewer than N distinct held grasps also gets --n grasps by "
                        f"optimization from scratch, and the distinct held grasps are chosen from both (default {DEFAULT_MIN_DISTINCT}: a handful of "
                        "different grasps, so a robot can pick one whose approach is free; it costs the optimization's time on each such "
                        "object); 0: the model's grasps only")  # fmt: skip
    parser.add_argument("--top-up-batches", type=int, default=None, metavar="K",
                        help=f"with a model: the top-up optimizes batches of --n grasps on each short object until it has --min-distinct "
                        f"distinct held grasps, at most K batches (default {DEFAULT_TOP_UP_BATCHES}), none more after one that added it none")
    parser.add_argument("--from-scratch", action="store_true", help="energy optimization from scratch only, no model (slower per grasp)")
    parser.add_argument("--type-rounds", type=int, default=None, metavar="R",
                        help="with --from-scratch: optimize each object's --n starts in R rounds, the first dealt to the grasp types in "
                        "their configured shares (optimize_grasps.grasp_types), each later one to the types that held on that object so "
                        "far (Thompson sampling); default 1 round. Useful with several types: an object that only one type holds gets "
                        "most of its starts of that type")  # fmt: skip
    parser.add_argument("--grasp-type", default=None, metavar="TYPE",
                        help=f"the grasps' type: any (default: the model's training mix) or one of {', '.join(GRASP_TYPE_NAMES)}; the "
                        "model must know it (the shipped Shadow model knows all five), and optimization from scratch (--from-scratch, "
                        "the top-up) then makes that type only; a hand other than shadow offers power, pinch, tripod and rim as its "
                        "fingers allow (docs/hands.md)")
    parser.add_argument("--hand", default=None, metavar="HAND",
                        help="the hand: shadow (default: the config's hand), allegro, leap or the path of a hand's MJCF file "
                        "(docs/hands.md); a hand other than shadow needs a --model trained for it or --from-scratch (the shipped model is "
                        "the Shadow Hand's); its pictures and 3-D view draw the hand's collision shapes")
    parser.add_argument("--config-json", default="{}", help="config sections over the default config.yaml, as inline JSON or a .json/.yaml file")
    parser.add_argument("--renders", type=int, default=DEFAULT_RENDERS_PER_OBJECT, help="pictures per object (default %(default)s)")
    parser.add_argument("--upright-axis", choices=UPRIGHT_AXES, default=None, help="on a table (scene.table, the default): the mesh axis that "
                        "points up; default: each mesh's stable pose, where it comes to rest when set down in its file orientation")


def run(args: argparse.Namespace) -> int:
    import os

    from dexlite_pipeline.api import SHIPPED, grasp_request
    from dexlite_pipeline.config import parse_config_json
    from dexlite_pipeline.tools.grasp import GraspToolError, run_grasp_tool

    if args.evaluator and args.no_evaluator:
        raise GraspToolError("--evaluator and --no-evaluator exclude each other")
    request = grasp_request(
        args.meshes, args.out, args.n, args.units, model=args.model or SHIPPED, evaluator=None if args.no_evaluator else args.evaluator or SHIPPED,
        from_scratch=args.from_scratch, min_distinct=args.min_distinct, top_up_batches=args.top_up_batches,
        resize_to_training=args.resize_to_training, distinct=args.distinct, overwrite=args.overwrite, device=args.device,
        config=parse_config_json(args.config_json), threads=args.threads or os.cpu_count() or 1, renders=args.renders,
        upright_axis=args.upright_axis, grasp_type=args.grasp_type, hand=args.hand, type_rounds=args.type_rounds,
    )  # fmt: skip
    outcome = run_grasp_tool(request)
    print(f"{outcome.held}/{outcome.total} grasps held the object in the lift test, {outcome.distinct} distinct "
          f"({len(outcome.objects)} object(s), {outcome.seconds:.0f} s) -> {outcome.summary_path}")
    if outcome.topped_up:
        print(f"optimization from scratch topped up the model's grasps of {len(outcome.topped_up)} object(s): {', '.join(outcome.topped_up)}")
    for hint in outcome.next_steps:
        print(f"next: {hint.replace('`', '')}")
    if not outcome.held:
        log.error("no grasp held; the summary lists why each failed and what to try: %s", outcome.summary_path)
        return 1
    return 0
