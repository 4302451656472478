# Seed synthesis: optimize grasps from scratch for each shard's stable objects (train and held-out).


rule seed_grasps:
    input:
        catalog=f"{RESULTS}/objects/catalog.parquet",
        stability=f"{RESULTS}/stability/stability.parquet",
    output:
        grasps=directory(f"{RESULTS}/seed/shard_{{shard}}.zarr"),
    params:
        cfg=stage_params("seed", "device", "shards", "energy", "scene", "seed_grasps"),
        code=code_hash("seed_grasps"),
        objects=lambda wildcards, input: Path(input.catalog).parent,
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/seed_grasps/shard_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/seed_grasps_{{shard}}.tsv"
    shell:
        "dexlite seed-grasps --config-json {params.cfg:q} --shard {wildcards.shard} --stability {input.stability} "
        "--objects {params.objects} --out {output.grasps} --threads {threads} > {log} 2>&1"
