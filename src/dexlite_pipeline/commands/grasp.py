"""``dexlite grasp MESH [MESH ...] --out DIR``: grasps that hold for your own meshes, in one command.

Prepares the meshes (a folder of .obj/.stl files works too), synthesizes grasps (with the
shipped model when the checkout has it; by optimization from scratch without one or with
``--from-scratch``), keeps those that pass the lift test and writes ``DIR/grasps.zarr``, ``DIR/dexgraspnet/``,
``DIR/renders/`` and ``DIR/summary.md`` (``dexlite_pipeline.tools.grasp``). On a table (``scene.table``,
the default) each mesh stands in its stable pose, or with ``--upright-axis`` up; the log says which. Exit status 0
when some grasp held, 1 when none did (the outputs are written all the same), 2 for
unusable input.
"""

from __future__ import annotations

import argparse
import logging

log = logging.getLogger("dexlite.grasp")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from dexlite_pipeline.tabletop import UPRIGHT_AXES
    from dexlite_pipeline.tools.grasp import DEFAULT_GRASPS_PER_OBJECT, DEFAULT_RENDERS_PER_OBJECT

    parser.add_argument("meshes", nargs="+", help=".obj/.stl mesh files, or folders of them")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--n", type=int, default=DEFAULT_GRASPS_PER_OBJECT, help="grasps synthesized per object (default %(default)s)")
    parser.add_argument("--real-size", action="store_true", help="keep each mesh's own size, its units read as metres (default: the configured scales)")
    parser.add_argument("--device", default=None, help="auto, cpu, cuda or cuda:N (default: the config's device)")
    parser.add_argument("--model", default=None, help="trained model (cvae.pt) to sample and post-optimize with (default: the shipped "
                        "model, models/shadow-hand-large/cvae.pt, when this checkout has it)")
    parser.add_argument("--from-scratch", action="store_true", help="energy optimization from scratch instead of a model (slower per grasp)")
    parser.add_argument("--config-json", default="{}", help="config sections over config.yaml, as inline JSON or a .json/.yaml file")
    parser.add_argument("--renders", type=int, default=DEFAULT_RENDERS_PER_OBJECT, help="pictures per object (default %(default)s)")
    parser.add_argument("--upright-axis", choices=UPRIGHT_AXES, default=None, help="on a table (scene.table, the default): the mesh axis that "
                        "points up; default: each mesh's stable pose, where it comes to rest when set down in its file orientation")


def run(args: argparse.Namespace) -> int:
    import os

    from dexlite_pipeline.config import parse_config_json
    from dexlite_pipeline.model.shipped import shipped_model_path
    from dexlite_pipeline.tools.grasp import GraspRequest, run_grasp_tool

    if args.from_scratch and args.model:
        log.error("--from-scratch and --model exclude each other")
        return 2
    shipped = shipped_model_path()
    model = None if args.from_scratch else (args.model or (str(shipped) if shipped else None))
    if model is None and not args.from_scratch:
        log.info("no model given and no shipped model in this checkout: optimizing from scratch")
    request = GraspRequest(
        meshes=args.meshes, out_dir=args.out, grasps_per_object=args.n, real_size=args.real_size, device=args.device,
        model=model, config=parse_config_json(args.config_json), threads=args.threads or os.cpu_count() or 1,
        renders_per_object=args.renders, upright_axis=args.upright_axis,
    )  # fmt: skip
    outcome = run_grasp_tool(request)
    print(f"{outcome.held}/{outcome.total} grasps held the object in the lift test ({len(outcome.objects)} object(s), "
          f"{outcome.seconds:.0f} s) -> {outcome.summary_path}")
    if not outcome.held:
        log.error("no grasp held; see %s (raise --n, or check the mesh's size and units)", outcome.summary_path)
        return 1
    return 0
