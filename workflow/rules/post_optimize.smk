# Learning: refine each shard's CVAE grasps on E_post, plus the random-init baseline (same budget).


rule post_optimize:
    input:
        sample=f"{RESULTS}/sample/shard_{{shard}}.zarr",
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        post=directory(f"{RESULTS}/post/shard_{{shard}}.zarr"),
        random=directory(f"{RESULTS}/post/random_shard_{{shard}}.zarr"),
    params:
        cfg=stage_params("seed", "device", "post_optimize", "energy.self_penetration_margin_m"),
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
        "dexlite post-optimize --config-json {params.cfg:q} --sample {input.sample} {params.objects} "
        "--shard {wildcards.shard} --out {output.post} --random-out {output.random} --threads {threads} > {log} 2>&1"
