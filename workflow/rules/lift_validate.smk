# Physics validation: MuJoCo lift test (and, with lift.six_directions, the six-direction
# test) of each shard's curated grasps, on each object's table in tabletop mode (scene.table;
# the resting poses come from the stability table). Later stages train on lift_success only.


rule lift_validate:
    input:
        grasps=f"{RESULTS}/curate/shard_{{shard}}.zarr",
        catalog=f"{RESULTS}/objects/catalog.parquet",
        stability=f"{RESULTS}/stability/stability.parquet",
    output:
        directory(f"{RESULTS}/lift/shard_{{shard}}.zarr"),
    params:
        cfg=stage_params("seed", "hand", "lift", "scene"),
        code=code_hash("lift_validate"),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/lift_validate/shard_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/lift_validate_{{shard}}.tsv"
    shell:
        "dexlite lift-validate --config-json {params.cfg:q} --grasps {input.grasps} --stability {input.stability} {params.objects} "
        "--shard {wildcards.shard} --out {output} --threads {threads} > {log} 2>&1"
