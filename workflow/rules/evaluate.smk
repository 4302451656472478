# Evaluation on held-out objects: simulate each shard of every method's grasps (on each object's
# table in tabletop mode; in both modes the resting poses give each grasp's reach below the table),
# then tabulate, then build the HTML report. Which methods are read comes from config.evaluate.methods.
# Each step tracks only the evaluate keys it reads (evaluation.step_keys): a report-only setting
# reruns the report, a metric setting the aggregate step and the report, not the simulation.
from dexlite_pipeline.evaluation.step_keys import AGGREGATE_KEYS, SIMULATE_KEYS, SOURCE_OPTIONS, sources_of, with_evaluate_keys


def evaluate_step_params(keys, *sections):
    """``sections`` plus the given keys of config.evaluate (stage_params): what one evaluation step tracks."""
    return stage_params("evaluate", *sections, source=with_evaluate_keys(config, keys))


# Where each grasp source's store of a shard is (the method -> source map is step_keys.METHOD_SOURCES).
SOURCE_STORES = {
    "optimized": f"{RESULTS}/optimized/shard_{{shard}}.zarr",
    "sample": f"{RESULTS}/sample/shard_{{shard}}.zarr",
    "post": f"{RESULTS}/post/shard_{{shard}}.zarr",
    "random_post": f"{RESULTS}/post/random_shard_{{shard}}.zarr",
    "dexgraspnet": f"{RESULTS}/dexgraspnet/grasps.zarr",
}


def _evaluate_sources(shard):
    """Grasp store of one shard per source the configured methods read (dexgraspnet only when configured)."""
    sources = sources_of(config["evaluate"]["methods"])
    return {
        source: SOURCE_STORES[source].format(shard=shard)
        for source in sources
        if source != "dexgraspnet" or config["dexgraspnet"]["root"]
    }


def _post_stores(source):
    """Every shard's store of a post-optimization source, when a configured method reads it (its traces make convergence.csv)."""
    return expand(SOURCE_STORES[source], shard=SHARDS) if source in sources_of(config["evaluate"]["methods"]) else []


rule evaluate_simulate:
    input:
        unpack(lambda wc: {"catalog": f"{RESULTS}/objects/catalog.parquet", "stability": f"{RESULTS}/stability/stability.parquet",
                           **_evaluate_sources(wc.shard)}),
    output:
        directory(f"{RESULTS}/eval/sim/shard_{{shard}}.zarr"),
    threads: SHARD_THREADS
    params:
        cfg=evaluate_step_params(SIMULATE_KEYS, "seed", "device", "shards", "lift", "energy", "scene"),
        code=code_hash("evaluate"),
        sources=lambda wc: " ".join(f"--{SOURCE_OPTIONS[k]} {v}" for k, v in _evaluate_sources(wc.shard).items()),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/evaluate/simulate_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/evaluate_simulate_{{shard}}.tsv"
    shell:
        "dexlite evaluate --step simulate --config-json {params.cfg:q} --shard {wildcards.shard} {params.sources} "
        "--stability {input.stability} {params.objects} --out {output} --threads {threads} > {log} 2>&1"


rule evaluate:
    input:
        sims=expand(f"{RESULTS}/eval/sim/shard_{{shard}}.zarr", shard=SHARDS),
        post=_post_stores("post"),
        random_post=_post_stores("random_post"),
    output:
        metrics=f"{RESULTS}/eval/metrics.csv",
        per_object=f"{RESULTS}/eval/per_object.csv",
        convergence=f"{RESULTS}/eval/convergence.csv",
        budget=f"{RESULTS}/eval/budget.csv",
        record=f"{RESULTS}/eval/evaluation.json",
    threads: 1
    params:
        cfg=evaluate_step_params(AGGREGATE_KEYS, "seed", "diversity"),
        code=code_hash("evaluate"),
        sims=lambda wc, input: learning_cli_options("sim", input.sims),
        post=lambda wc, input: learning_cli_options("post", input.post) + " " + learning_cli_options("random-post", input.random_post),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/evaluate/aggregate.log",
    benchmark:
        f"{LOGS}/benchmarks/evaluate.tsv"
    shell:
        "dexlite evaluate --step aggregate --config-json {params.cfg:q} {params.sims} {params.post} {params.objects} "
        "--metrics {output.metrics} --per-object {output.per_object} --convergence {output.convergence} "
        "--budget {output.budget} --record {output.record} > {log} 2>&1"


# The shipped model's learning curve, shown in the report when the checkout has it.
LEARNING_CURVE = Path(workflow.basedir) / "docs" / "learning_curve.csv"
# The data loop's table, shown in the report when the run has rounds; with loop.rounds 0 the rule's
# inputs, params and command are exactly those of the workflow without the loop.
REPORT_LOOP_OPTION = "--loop {input.loop} " if LOOP_ROUNDS else ""


rule report:
    input:
        unpack(lambda wc: {"learning_curve": checkout_file("docs/learning_curve.csv")} if LEARNING_CURVE.is_file() else {}),
        unpack(lambda wc: {"loop": f"{RESULTS}/loop.csv"} if LOOP_ROUNDS else {}),
        metrics=f"{RESULTS}/eval/metrics.csv",
        per_object=f"{RESULTS}/eval/per_object.csv",
        convergence=f"{RESULTS}/eval/convergence.csv",
        budget=f"{RESULTS}/eval/budget.csv",
        record=f"{RESULTS}/eval/evaluation.json",
        sims=expand(f"{RESULTS}/eval/sim/shard_{{shard}}.zarr", shard=SHARDS),
        history=f"{RESULTS}/model/history.csv",
    output:
        f"{RESULTS}/eval/report.html",
    threads: 1
    params:
        # the whole config: the report shows it (last stage, so nothing else reruns); a loop of no rounds is not shown
        cfg=stage_params(*sorted(section for section in config if section != "loop" or LOOP_ROUNDS)),
        code=code_hash("report"),
        sims=lambda wc, input: learning_cli_options("sim", input.sims),
        objects=learning_cli_options("objects", learning_objects_dirs()),
        curve=lambda wc, input: f"--learning-curve {shlex.quote(input.learning_curve)}" if "learning_curve" in input.keys() else "",
        benchmarks=f"{LOGS}/benchmarks",  # the jobs' benchmark files: the run's wall time at the top of the report
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/report.log",
    benchmark:
        f"{LOGS}/benchmarks/report.tsv"
    shell:
        "dexlite report --config-json {params.cfg:q} --metrics {input.metrics} --per-object {input.per_object} "
        "--convergence {input.convergence} --budget {input.budget} --record {input.record} {params.sims} --history {input.history} "
        "{params.objects} {params.curve} " + REPORT_LOOP_OPTION + "--benchmarks {params.benchmarks} --out {output} > {log} 2>&1"
