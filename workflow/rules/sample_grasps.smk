# Learning: CVAE grasps per shard (pure synthesis on held-out objects, expansion on training objects, and the
# shipped model's syntheses on held-out objects it never trained on).


SHIPPED_METHODS = {"shipped_raw", "shipped_post"}
if SHIPPED_METHODS & set(config["evaluate"]["methods"]) and not config["sample"].get("shipped_model"):
    raise WorkflowError('evaluate.methods: shipped_raw and shipped_post need sample.shipped_model (the pretrained model file); drop them or set it')
if config["sample"].get("shipped_model") and not (Path(workflow.basedir) / config["sample"]["shipped_model"]).is_file():
    raise WorkflowError(f'sample.shipped_model: {config["sample"]["shipped_model"]} is not a file in {workflow.basedir} (set it to "" to run without it)')


def shipped_model_input(wildcards):
    """The shipped model file (sample.shipped_model, relative to this checkout) when configured: an input, so
    replacing it reruns sampling."""
    path = config["sample"].get("shipped_model") or ""
    return {"shipped": checkout_file(path)} if path else {}


# What the ranking reads besides the sample section, tracked only when it runs (evaluator.enabled): the pool, what
# "distinct" means and how many grasps per object the evaluation simulates (as many ranked rows are kept)
RANKING_SECTIONS = ("evaluator.pool_factor", "diversity", "evaluate.grasps_per_object") if config["evaluator"]["enabled"] else ()


rule sample_grasps:
    input:
        unpack(shipped_model_input),
        unpack(evaluator_input),  # with evaluator.enabled: rank pooled syntheses on held-out objects (evaluator.smk)
        model=final_model(),  # the data loop's last model (train_cvae's without the loop)
        stability=f"{RESULTS}/stability/stability.parquet",
        # the expansion's seeds: the lift-validated grasps, with or without the data loop (docs/design.md, "The data loop")
        lift=training_grasp_stores(),
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        directory(f"{RESULTS}/sample/shard_{{shard}}.zarr"),
    params:
        cfg=stage_params("seed", "device", "shards", "sample", "scene", *RANKING_SECTIONS),  # scene: the table frame the model reads
        code=code_hash("sample_grasps"),
        lift=lambda wc, input: learning_cli_options("lift", input.lift),
        objects=learning_cli_options("objects", learning_objects_dirs()),
        shipped=lambda wc, input: f"--shipped-model {shlex.quote(input.shipped)}" if "shipped" in input.keys() else '--shipped-model ""',
        evaluator=lambda wc, input: f"--evaluator {shlex.quote(input.evaluator)}" if "evaluator" in input.keys() else "",
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/sample_grasps/shard_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/sample_grasps_{{shard}}.tsv"
    shell:
        "dexlite sample-grasps --config-json {params.cfg:q} --model {input.model} --stability {input.stability} "
        "{params.lift} {params.objects} {params.shipped} {params.evaluator} --shard {wildcards.shard} --out {output} --threads {threads} > {log} 2>&1"
