# The data loop (Dex1B), config section loop; nothing here runs with loop.rounds 0. Round r >= 1:
# round r-1's model samples grasps on every stable training object (part "train"), they are post-optimized,
# filtered by energy, lift- and six-direction-tested (on each object's table in tabletop mode), the new
# distinct ones join round r-1's set and round r's model trains on it, warm-started. Every round's model
# (round 0's included) is also checked on the held-out objects (part "heldout", a small cap). Outputs go to
# results/round_<r>/; results/loop.csv has a row per round. The rules track loop's keys one by one, never
# loop.rounds: more or fewer rounds add or drop rounds' jobs and rerun what reads the final model, not the rounds kept.
# What each rule passes its stage: loop.config.loop_rule_sections (a loop key names its rules in its setting).
from dexlite_pipeline.loop.config import loop_rule_sections

ROUND = f"{RESULTS}/round_{{round}}"


wildcard_constraints:
    round=r"\d+",
    part="train|heldout",


def loop_sample_model(wildcards):
    """A round's candidates come from the previous round's model; its held-out check is of its own model."""
    round_number = int(wildcards.round)
    return round_model(round_number - 1 if wildcards.part == "train" else round_number)


rule loop_initial_set:
    input:
        lift=training_grasp_stores(),
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        directory(f"{RESULTS}/round_0/grasps.zarr"),
    params:
        code=code_hash("loop_initial_set"),
        lift=lambda wc, input: learning_cli_options("lift", input.lift),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: 1
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/loop/initial_set.log",
    benchmark:
        f"{LOGS}/benchmarks/loop_initial_set.tsv"
    shell:
        "dexlite loop-initial-set {params.lift} {params.objects} --out {output} > {log} 2>&1"


LOOP_RANKING = bool(config["loop"]["rank_candidates"])
if LOOP_RANKING and not config["evaluator"]["enabled"]:
    raise WorkflowError("loop.rank_candidates needs the learned evaluator (evaluator.enabled: true)")


def loop_ranking_input(wildcards):
    """The learned evaluator for a round's candidates on training objects, with loop.rank_candidates."""
    return evaluator_input(wildcards) if LOOP_RANKING and wildcards.part == "train" else {}


rule loop_sample:
    input:
        unpack(loop_ranking_input),
        model=loop_sample_model,
        stability=f"{RESULTS}/stability/stability.parquet",
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        directory(f"{ROUND}/{{part}}/sample_{{shard}}.zarr"),
    params:
        cfg=stage_params(*loop_rule_sections("loop_sample"), *(("evaluator.pool_factor", "diversity") if LOOP_RANKING else ())),
        code=code_hash("loop_sample"),
        evaluator=lambda wc, input: f"--evaluator {input.evaluator}" if "evaluator" in input.keys() else "",
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/loop/round_{{round}}/{{part}}_sample_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/loop_sample_{{round}}_{{part}}_{{shard}}.tsv"
    shell:
        "dexlite loop-sample --config-json {params.cfg:q} --model {input.model} {params.evaluator} --stability {input.stability} {params.objects} "
        "--round {wildcards.round} --part {wildcards.part} --shard {wildcards.shard} --out {output} --threads {threads} > {log} 2>&1"


rule loop_post_optimize:
    input:
        sample=f"{ROUND}/{{part}}/sample_{{shard}}.zarr",
        stability=f"{RESULTS}/stability/stability.parquet",
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        directory(f"{ROUND}/{{part}}/post_{{shard}}.zarr"),
    params:
        cfg=stage_params(*loop_rule_sections("loop_post_optimize")),
        code=code_hash("loop_post_optimize"),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/loop/round_{{round}}/{{part}}_post_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/loop_post_optimize_{{round}}_{{part}}_{{shard}}.tsv"
    shell:
        "dexlite loop-post-optimize --config-json {params.cfg:q} --sample {input.sample} --stability {input.stability} {params.objects} "
        "--round {wildcards.round} --part {wildcards.part} --shard {wildcards.shard} --out {output} --threads {threads} > {log} 2>&1"


rule loop_validate:
    input:
        grasps=f"{ROUND}/{{part}}/post_{{shard}}.zarr",
        stability=f"{RESULTS}/stability/stability.parquet",
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        directory(f"{ROUND}/{{part}}/validated_{{shard}}.zarr"),
    params:
        cfg=stage_params(*loop_rule_sections("loop_validate")),
        code=code_hash("loop_validate"),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: SHARD_THREADS
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/loop/round_{{round}}/{{part}}_validate_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/loop_validate_{{round}}_{{part}}_{{shard}}.tsv"
    shell:
        "dexlite loop-validate --config-json {params.cfg:q} --grasps {input.grasps} --stability {input.stability} {params.objects} "
        "--round {wildcards.round} --part {wildcards.part} --shard {wildcards.shard} --out {output} --threads {threads} > {log} 2>&1"


rule loop_merge:
    input:
        previous=lambda wc: f"{RESULTS}/round_{int(wc.round) - 1}/grasps.zarr",
        validated=expand(f"{ROUND}/train/validated_{{shard}}.zarr", shard=SHARDS, allow_missing=True),
    output:
        directory(f"{RESULTS}/round_{{round,[1-9][0-9]*}}/grasps.zarr"),
    params:
        cfg=stage_params(*loop_rule_sections("loop_merge")),
        code=code_hash("loop_merge"),
        validated=lambda wc, input: learning_cli_options("validated", input.validated),
    threads: 1
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/loop/round_{{round}}/merge.log",
    benchmark:
        f"{LOGS}/benchmarks/loop_merge_{{round}}.tsv"
    shell:
        "dexlite loop-merge --config-json {params.cfg:q} --previous {input.previous} {params.validated} --round {wildcards.round} "
        "--out {output} > {log} 2>&1"


rule loop_train:
    input:
        grasps=f"{ROUND}/grasps.zarr",
        initial=lambda wc: round_model(int(wc.round) - 1),
        stability=f"{RESULTS}/stability/stability.parquet",
        catalog=f"{RESULTS}/objects/catalog.parquet",
    output:
        model=f"{RESULTS}/round_{{round,[1-9][0-9]*}}/model/cvae.pt",
        history=f"{ROUND}/model/history.csv",
        curves=f"{ROUND}/model/training_curves.png",
    params:
        cfg=stage_params(*loop_rule_sections("loop_train")),
        code=code_hash("loop_train"),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: all_cores()
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/loop/round_{{round}}/train.log",
    benchmark:
        f"{LOGS}/benchmarks/loop_train_{{round}}.tsv"
    shell:
        "dexlite loop-train --config-json {params.cfg:q} --grasps {input.grasps} --initial-model {input.initial} --stability {input.stability} "
        "{params.objects} --round {wildcards.round} --model {output.model} --history {output.history} --curves {output.curves} "
        "--threads {threads} > {log} 2>&1"


def loop_summary_inputs(wildcards):
    """The round's set, its held-out check, and (round >= 1) the stores of its candidates and its model."""
    round_number = int(wildcards.round)
    steps = ("sample", "post", "validated")
    inputs = {
        "grasps": f"{RESULTS}/round_{round_number}/grasps.zarr",
        "heldout": [f"{RESULTS}/round_{round_number}/heldout/validated_{shard}.zarr" for shard in SHARDS],
        "heldout_cost": [f"{RESULTS}/round_{round_number}/heldout/{step}_{shard}.zarr" for step in steps for shard in SHARDS],
        "stability": f"{RESULTS}/stability/stability.parquet",
        "catalog": f"{RESULTS}/objects/catalog.parquet",
    }
    if round_number > 0:
        inputs["cost"] = [f"{RESULTS}/round_{round_number}/train/{step}_{shard}.zarr" for step in steps for shard in SHARDS]
        inputs["cost"].append(inputs["grasps"])
        inputs["model"] = round_model(round_number)
    return inputs


def loop_summary_options(input):
    options = " ".join(f"--heldout {p}" for p in input.heldout) + " " + " ".join(f"--heldout-cost {p}" for p in input.heldout_cost)
    if "model" in input.keys():
        options += " " + " ".join(f"--cost {p}" for p in input.cost) + f" --model {input.model}"
    return options


rule loop_summary:
    input:
        unpack(loop_summary_inputs),
    output:
        table=f"{ROUND}/summary.csv",
        row=f"{ROUND}/round.json",
    params:
        cfg=stage_params(*loop_rule_sections("loop_summary")),
        code=code_hash("loop_summary"),
        options=lambda wc, input: loop_summary_options(input),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: 1
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/loop/round_{{round}}/summary.log",
    benchmark:
        f"{LOGS}/benchmarks/loop_summary_{{round}}.tsv"
    shell:
        "dexlite loop-summary --config-json {params.cfg:q} --round {wildcards.round} --grasps {input.grasps} {params.options} "
        "{params.objects} --stability {input.stability} --table {output.table} --row {output.row} > {log} 2>&1"


rule loop_table:
    input:
        [f"{RESULTS}/round_{r}/round.json" for r in range(LOOP_ROUNDS + 1)],
    output:
        f"{RESULTS}/loop.csv",
    params:
        code=code_hash("loop_table"),
        rows=lambda wc, input: " ".join(f"--row {p}" for p in input),
    threads: 1
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/loop/table.log",
    benchmark:
        f"{LOGS}/benchmarks/loop_table.tsv"
    shell:
        "dexlite loop-table {params.rows} --out {output} > {log} 2>&1"


localrules:
    loop_table,
