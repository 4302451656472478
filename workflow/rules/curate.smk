# Curation: per shard, keep the optimized (and imported DexGraspNet) grasps of stable training
# objects that meet the energy thresholds, without near-duplicates, capped per object;
# then merge the per-shard summaries into results/curate/summary.csv.


def curate_inputs(wildcards):
    inputs = {
        "optimized": f"{RESULTS}/optimized/shard_{wildcards.shard}.zarr",
        "stability": f"{RESULTS}/stability/stability.parquet",
        "catalog": f"{RESULTS}/objects/catalog.parquet",
    }
    if config["dexgraspnet"]["root"]:
        inputs["imported"] = f"{RESULTS}/dexgraspnet/grasps.zarr"
        inputs["imported_catalog"] = f"{RESULTS}/dexgraspnet/objects/catalog.parquet"
    return inputs


def curate_options(input):
    """--objects for every catalog, --imported when DexGraspNet grasps are curated too."""
    options = f"--objects {Path(input.catalog).parent}"
    if "imported" in input.keys():
        options += f" --objects {Path(input.imported_catalog).parent} --imported {input.imported}"
    return options


# Device, shards and energy matter only for imported grasps (dealt to shards here, their energies computed here);
# scene: on a table, grasps with a hand point below it are dropped (below_table); hand: the stores' hand.
CURATE_SECTIONS = ("curate", "scene", "hand") + (("device", "shards", "energy") if config["dexgraspnet"]["root"] else ())


rule curate:
    input:
        unpack(curate_inputs),
    output:
        grasps=directory(f"{RESULTS}/curate/shard_{{shard}}.zarr"),
        summary=f"{RESULTS}/curate/summary_{{shard}}.csv",
    params:
        cfg=stage_params(*CURATE_SECTIONS),
        code=code_hash("curate"),
        options=lambda wildcards, input: curate_options(input),
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/curate/shard_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/curate_{{shard}}.tsv"
    shell:
        "dexlite curate --step curate --shard {wildcards.shard} --config-json {params.cfg:q} --optimized-grasps {input.optimized} "
        "--stability {input.stability} {params.options} --out {output.grasps} --summary-out {output.summary} "
        "--threads {threads} > {log} 2>&1"


rule curate_summary:
    input:
        expand(f"{RESULTS}/curate/summary_{{shard}}.csv", shard=SHARDS),
    output:
        f"{RESULTS}/curate/summary.csv",
    params:
        code=code_hash("curate"),
        summaries=lambda wildcards, input: " ".join(f"--summary {p}" for p in input),
    threads: 1
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/curate/summary.log",
    benchmark:
        f"{LOGS}/benchmarks/curate_summary.tsv"
    shell:
        "dexlite curate --step aggregate {params.summaries} --out {output} > {log} 2>&1"


localrules:
    curate_summary,
