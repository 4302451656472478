# The learned grasp evaluator (config section evaluator; nothing here runs with evaluator.enabled false): the final
# model's syntheses on every stable training object, refined and simulated (on-generator examples), then an evaluator
# trained on those and the lift-validated grasps of the training objects. sample_grasps ranks a larger pool of
# syntheses on held-out objects by it (rows cvae_ranked*, listed in evaluate.methods); with loop.rank_candidates the
# loop's rounds rank their candidates by it (the examples then come from round 0's model). With evaluator.source shipped
# or a file, that evaluator ranks and nothing here runs.

from dexlite_pipeline.evaluation.config import RANKED_METHODS

if not config["evaluator"]["enabled"]:  # without the evaluator there are no ranked rows to measure
    config["evaluate"]["methods"] = [m for m in config["evaluate"]["methods"] if m not in RANKED_METHODS]


def ranking_evaluator():
    """The evaluator that ranks: the one the run trains (evaluator.source: train) or the file evaluator.source names."""
    from dexlite_pipeline.model.shipped import ranking_evaluator_file

    try:
        given = ranking_evaluator_file(str(config["evaluator"]["source"]), str(config["hand"]))
    except FileNotFoundError as error:
        raise WorkflowError(str(error)) from None
    return str(given) if given is not None else f"{RESULTS}/evaluator/evaluator.pt"


def evaluator_input(wildcards):
    """The ranking evaluator when evaluator.enabled: an input of sample_grasps, which then ranks by it."""
    return {"evaluator": ranking_evaluator()} if config["evaluator"]["enabled"] else {}


def examples_model():
    """The model whose samples the evaluator learns from: the one the evaluation samples from (the loop's last), or
    round 0's when the loop's rounds rank their candidates by the evaluator (which they need before the last model exists)."""
    return round_model(0) if config["loop"]["rank_candidates"] else final_model()


rule evaluator_examples:
    input:
        model=examples_model(),
        stability=f"{RESULTS}/stability/stability.parquet",
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        directory(f"{RESULTS}/evaluator/examples_{{shard}}.zarr"),
    params:
        cfg=stage_params("seed", "device", "shards", "sample", "post_optimize", "scene", "curate", "energy", "lift", "evaluator.examples_per_object"),
        code=code_hash("evaluator_examples"),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/evaluator/examples_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/evaluator_examples_{{shard}}.tsv"
    shell:
        "dexlite evaluator-examples --config-json {params.cfg:q} --model {input.model} --stability {input.stability} {params.objects} "
        "--shard {wildcards.shard} --out {output} --threads {threads} > {log} 2>&1"


rule train_evaluator:
    input:
        lift=training_grasp_stores(),
        examples=expand(f"{RESULTS}/evaluator/examples_{{shard}}.zarr", shard=SHARDS),
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        model=f"{RESULTS}/evaluator/evaluator.pt",
        facts=f"{RESULTS}/evaluator/training.json",
    params:
        cfg=stage_params("seed", "device", "train.seed", "evaluator.epochs", "evaluator.hand_points_per_shape", "evaluator.validation_fraction"),
        code=code_hash("train_evaluator"),
        lift=lambda wc, input: learning_cli_options("lift", input.lift),
        examples=lambda wc, input: learning_cli_options("examples", input.examples),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: all_cores()
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/evaluator/train.log",
    benchmark:
        f"{LOGS}/benchmarks/train_evaluator.tsv"
    shell:
        "dexlite train-evaluator --config-json {params.cfg:q} {params.lift} {params.examples} {params.objects} "
        "--out {output.model} --facts {output.facts} --threads {threads} > {log} 2>&1"
