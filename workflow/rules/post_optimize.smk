# Learning: refine each shard's CVAE grasps on E_post, plus the random-init baseline (same budget); on each
# object's table in tabletop mode (scene.table: E_table, starts above the table).


rule post_optimize:
    input:
        sample=f"{RESULTS}/sample/shard_{{shard}}.zarr",
        catalog=f"{RESULTS}/objects/catalog.parquet",
        stability=f"{RESULTS}/stability/stability.parquet",
    output:
        post=directory(f"{RESULTS}/post/shard_{{shard}}.zarr"),
        random=directory(f"{RESULTS}/post/random_shard_{{shard}}.zarr"),
    params:
        cfg=stage_params("seed", "device", "post_optimize", "scene", "energy.self_penetration_margin_m"),
        code=code_hash("post_optimize"),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/post_optimize/shard_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/post_optimize_{{shard}}.tsv"
    shell:
        "dexlite post-optimize --config-json {params.cfg:q} --sample {input.sample} --stability {input.stability} {params.objects} "
        "--shard {wildcards.shard} --out {output.post} --random-out {output.random} --threads {threads} > {log} 2>&1"
