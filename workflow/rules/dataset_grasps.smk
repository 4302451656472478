# With dataset.root: the grasp dataset's grasps of each shard's training objects, read by the learning stages beside
# the lift-validation shards (those objects are not optimized: optimize_grasps.smk).


rule dataset_grasps:
    input:
        dataset=dataset_files,
        catalog=f"{RESULTS}/objects/catalog.parquet",
        stability=f"{RESULTS}/stability/stability.parquet",
    output:
        directory(f"{RESULTS}/dataset/shard_{{shard}}.zarr"),
    params:
        cfg=stage_params("shards", "scene"),
        code=code_hash("dataset_grasps"),
        root=lambda wc: shlex.quote(dataset_root()),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: 1
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/dataset_grasps/shard_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/dataset_grasps_{{shard}}.tsv"
    shell:
        "dexlite dataset-grasps --config-json {params.cfg:q} --dataset {params.root} --stability {input.stability} {params.objects} "
        "--shard {wildcards.shard} --out {output} > {log} 2>&1"
