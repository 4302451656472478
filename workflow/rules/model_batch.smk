# A dataset batch made by the model (config/profiles/household_model_batch.yaml): per shard, the generator's grasps
# on the stable objects, ranked, refined and tested, optimization from scratch topping up the objects short of
# distinct held grasps; `dexlite dataset-add` adds results/model_batch as a batch of kind model. Not in `all`:
# target model_batch_all (Snakefile). With config key hand, that hand's: model_batch.model and .evaluator must be of it.


rule model_batch:
    input:
        catalog=f"{RESULTS}/objects/catalog.parquet",
        stability=f"{RESULTS}/stability/stability.parquet",
        generator=model_batch_generator_files,
    output:
        directory(f"{RESULTS}/model_batch/shard_{{shard}}.zarr"),
    params:
        cfg=stage_params("seed", "device", "shards", "scene", "model_batch", "sample", "post_optimize", "evaluator", "optimize_grasps",
                         "energy", "diversity", "lift"),
        code=code_hash("model_batch"),
        objects=lambda wildcards, input: Path(input.catalog).parent,
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/model_batch/shard_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/model_batch_{{shard}}.tsv"
    shell:
        "dexlite model-batch --config-json {params.cfg:q} --shard {wildcards.shard} --stability {input.stability} "
        "--objects {params.objects} --out {output} --threads {threads} > {log} 2>&1"

