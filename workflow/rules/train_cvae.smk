# Learning: train the PointNet + CVAE on the lift-validated grasps of training objects.


rule train_cvae:
    input:
        lift=training_grasp_stores(),  # lift-validated shards (and the grasp dataset's, dataset.root)
        catalog=f"{RESULTS}/objects/catalog.parquet",
        stability=f"{RESULTS}/stability/stability.parquet",
    output:
        model=f"{RESULTS}/model/cvae.pt",
        history=f"{RESULTS}/model/history.csv",
        curves=f"{RESULTS}/model/training_curves.png",
    params:
        cfg=stage_params("seed", "device", "train", "scene", "energy.self_penetration_margin_m"),
        code=code_hash("train_cvae"),
        lift=lambda wc, input: learning_cli_options("lift", input.lift),
        objects=learning_cli_options("objects", learning_objects_dirs()),
    threads: all_cores()
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/train_cvae.log",
    benchmark:
        f"{LOGS}/benchmarks/train_cvae.tsv"
    shell:
        "dexlite train-cvae --config-json {params.cfg:q} {params.lift} --stability {input.stability} {params.objects} "
        "--model {output.model} --history {output.history} --curves {output.curves} --threads {threads} > {log} 2>&1"
