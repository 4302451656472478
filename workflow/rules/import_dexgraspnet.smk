# DexGraspNet import: grasps plus object assets in the dataset's own frame. Requested by
# curate and evaluate only when config dexgraspnet.root is set.
from dexlite_pipeline.config import IMPORT_ASSET_KEYS

DEXGRASPNET_ROOT = config["dexgraspnet"]["root"]
DEXGRASPNET_OBJECTS = f"{RESULTS}/dexgraspnet/objects"


def import_params():
    """Like stage_params, with only the asset keys of `objects` (others never rerun the import)."""
    objects = {k: v for k, v in config["objects"].items() if k in IMPORT_ASSET_KEYS}
    sections = {"seed": config["seed"], "objects": objects, "dexgraspnet": config["dexgraspnet"]}
    return json.dumps(sections, sort_keys=True, separators=(",", ":"))


rule import_dexgraspnet:
    input:
        dexgraspnet_files,
    output:
        grasps=directory(f"{RESULTS}/dexgraspnet/grasps.zarr"),
        catalog=f"{DEXGRASPNET_OBJECTS}/catalog.parquet",
        report=f"{RESULTS}/dexgraspnet/import_report.csv",
    params:
        cfg=import_params(),
        code=code_hash("import_dexgraspnet"),
        root=DEXGRASPNET_ROOT,
    threads: all_cores()
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/import_dexgraspnet.log",
    benchmark:
        f"{LOGS}/benchmarks/import_dexgraspnet.tsv"
    shell:
        "dexlite import-dexgraspnet {params.root:q} --config-json {params.cfg:q} --out {output.grasps} "
        "--catalog {output.catalog} --report {output.report} --threads {threads} > {log} 2>&1"
