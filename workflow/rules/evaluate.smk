# Evaluation on held-out objects: simulate each shard of every method's grasps, then tabulate,
# then build the HTML report. Which methods are read comes from config.evaluate.methods.
# learning_objects_dirs / learning_cli_options come from train_cvae.smk (included before).
# Each step tracks only the evaluate keys it reads (report.steps): a report-only setting
# reruns the report, a metric setting the aggregate step and the report, not the simulation.
from dexlite_pipeline.report.steps import AGGREGATE_KEYS, SIMULATE_KEYS, with_evaluate_keys


def evaluate_step_params(keys, *sections):
    """``sections`` plus the given keys of config.evaluate (stage_params): what one evaluation step tracks."""
    return stage_params("evaluate", *sections, source=with_evaluate_keys(config, keys))


def _evaluate_sources(shard):
    """Grasp stores of one shard per CLI option (--seed, --sample, ...), for the configured methods."""
    methods = (config.get("evaluate") or {}).get("methods", ["seed", "cvae_raw", "cvae_post", "random_post", "dexgraspnet"])
    sources = {}
    if "seed" in methods:
        sources["seed"] = f"{RESULTS}/seed/shard_{shard}.zarr"
    if any(m.startswith("cvae_") for m in methods):
        sources["sample"] = f"{RESULTS}/sample/shard_{shard}.zarr"
    if any(m.startswith("cvae_") and m.endswith("_post") for m in methods):
        sources["post"] = f"{RESULTS}/post/shard_{shard}.zarr"
    if "random_post" in methods:
        sources["random-post"] = f"{RESULTS}/post/random_shard_{shard}.zarr"
    if "dexgraspnet" in methods and config["dexgraspnet"]["root"]:
        sources["dexgraspnet"] = f"{RESULTS}/dexgraspnet/grasps.zarr"
    return sources


def _post_stores(prefix):
    methods = (config.get("evaluate") or {}).get("methods", ["cvae_post", "random_post"])
    wanted = "cvae_post" if prefix == "shard" else "random_post"
    return expand(f"{RESULTS}/post/{prefix}_{{shard}}.zarr", shard=SHARDS) if wanted in methods else []


rule evaluate_simulate:
    input:
        unpack(lambda wc: {"catalog": f"{RESULTS}/objects/catalog.parquet", **{k.replace("-", "_"): v for k, v in _evaluate_sources(wc.shard).items()}}),
    output:
        directory(f"{RESULTS}/eval/sim/shard_{{shard}}.zarr"),
    threads: SHARD_THREADS
    params:
        cfg=evaluate_step_params(SIMULATE_KEYS, "seed", "device", "shards", "lift", "energy"),
        code=code_hash("evaluate"),
        sources=lambda wc: " ".join(f"--{k} {v}" for k, v in _evaluate_sources(wc.shard).items()),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/evaluate/simulate_{{shard}}.log",
    benchmark:
        f"{LOGS}/benchmarks/evaluate_simulate_{{shard}}.tsv"
    shell:
        "dexlite evaluate --step simulate --config-json {params.cfg:q} --shard {wildcards.shard} {params.sources} "
        "{params.objects} --out {output} --threads {threads} > {log} 2>&1"


rule evaluate:
    input:
        sims=expand(f"{RESULTS}/eval/sim/shard_{{shard}}.zarr", shard=SHARDS),
        post=_post_stores("shard"),
        random_post=_post_stores("random_shard"),
    output:
        metrics=f"{RESULTS}/eval/metrics.csv",
        per_object=f"{RESULTS}/eval/per_object.csv",
        convergence=f"{RESULTS}/eval/convergence.csv",
        summary=f"{RESULTS}/eval/evaluation.json",
    threads: 1
    params:
        cfg=evaluate_step_params(AGGREGATE_KEYS, "seed"),
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
        "--out-dir {RESULTS}/eval > {log} 2>&1"


rule report:
    input:
        metrics=f"{RESULTS}/eval/metrics.csv",
        per_object=f"{RESULTS}/eval/per_object.csv",
        convergence=f"{RESULTS}/eval/convergence.csv",
        summary=f"{RESULTS}/eval/evaluation.json",
        sims=expand(f"{RESULTS}/eval/sim/shard_{{shard}}.zarr", shard=SHARDS),
        history=f"{RESULTS}/model/history.csv",
    output:
        f"{RESULTS}/eval/report.html",
    threads: 1
    params:
        cfg=stage_params(*sorted(config)),  # the whole config: the report shows it (last stage, so nothing else reruns)
        code=code_hash("report"),
        sims=lambda wc, input: learning_cli_options("sim", input.sims),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/report.log",
    benchmark:
        f"{LOGS}/benchmarks/report.tsv"
    shell:
        "dexlite report --config-json {params.cfg:q} --eval-dir {RESULTS}/eval {params.sims} --history {input.history} "
        "{params.objects} --out {output} > {log} 2>&1"
