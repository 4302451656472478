# The benchmark split (objects always held out) is data the stage reads: editing it reruns the stage.
BENCHMARK_SPLIT = checkout_file("src/dexlite_pipeline/objects/benchmark_split.yaml")
HOUSEHOLD_SPLIT = checkout_file("src/dexlite_pipeline/objects/household_split.yaml")
SHAPES_SPLIT = checkout_file("src/dexlite_pipeline/objects/shapes_split.yaml")


rule prepare_objects:
    input:
        meshes=mesh_dir_files,
        benchmark=BENCHMARK_SPLIT if config["objects"].get("benchmark_heldout", True) else [],
        household_split=HOUSEHOLD_SPLIT if config["objects"].get("household_benchmark_objects", 0) else [],
        shapes_split=SHAPES_SPLIT if config["objects"].get("shapes_benchmark_objects", 0) else [],
        dataset=dataset_object_tables,
    output:
        catalog=f"{RESULTS}/objects/catalog.parquet",
        config=f"{RESULTS}/objects/prepare_config.json",
    params:
        cfg=stage_params("seed", "objects", told_hand=False),
        code=code_hash("prepare_objects"),
        dataset=lambda wc: f"--dataset {shlex.quote(dataset_root())}" if config["objects"].get("dataset_objects") else "",
    threads: all_cores()
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/prepare_objects.log",
    benchmark:
        f"{LOGS}/benchmarks/prepare_objects.tsv"
    shell:
        "dexlite prepare-objects --config-json {params.cfg:q} --catalog {output.catalog} --record {output.config} --threads {threads} {params.dataset} > {log} 2>&1"
