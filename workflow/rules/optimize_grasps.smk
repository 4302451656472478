# Optimization from scratch: grasps for each shard's stable objects (train and held-out) by annealed energy optimization.


rule optimize_grasps:
    input:
        catalog=f"{RESULTS}/objects/catalog.parquet",
        stability=f"{RESULTS}/stability/stability.parquet",
        dataset=dataset_files,  # with dataset.root: its training objects are not optimized (their grasps come from it)
    output:
        grasps=directory(f"{RESULTS}/optimized/shard_{{shard}}.zarr"),
    params:
        cfg=stage_params("seed", "device", "shards", "hand", "energy", "scene", "optimize_grasps"),
        code=code_hash("optimize_grasps"),
        objects=lambda wildcards, input: Path(input.catalog).parent,
        dataset=f"--dataset {shlex.quote(dataset_root())}" if dataset_root() else "",
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/optimize_grasps/shard_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/optimize_grasps_{{shard}}.tsv"
    shell:
        "dexlite optimize-grasps --config-json {params.cfg:q} --shard {wildcards.shard} --stability {input.stability} "
        "--objects {params.objects} {params.dataset} --out {output.grasps} --threads {threads} > {log} 2>&1"
