# Learning: CVAE grasps per shard (pure synthesis on held-out objects, expansion on training objects).


rule sample_grasps:
    input:
        model=f"{RESULTS}/model/cvae.pt",
        stability=f"{RESULTS}/stability/stability.parquet",
        lift=expand(f"{RESULTS}/lift/shard_{{shard}}.zarr", shard=SHARDS),
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        directory(f"{RESULTS}/sample/shard_{{shard}}.zarr"),
    params:
        cfg=stage_params("seed", "device", "shards", "sample"),
        code=code_hash("sample_grasps"),
        lift=lambda wc, input: learning_cli_options("lift", input.lift),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/sample_grasps/shard_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/sample_grasps_{{shard}}.tsv"
    shell:
        "dexlite sample-grasps --config-json {params.cfg:q} --model {input.model} --stability {input.stability} "
        "{params.lift} {params.objects} --shard {wildcards.shard} --out {output} --threads {threads} > {log} 2>&1"
