# Table-stability filter (PyBullet): every prepared object, and the imported DexGraspNet
# objects when dexgraspnet.root is set, gets a row; later stages use stable objects only.


def stability_catalogs(wildcards):
    catalogs = [f"{RESULTS}/objects/catalog.parquet"]
    if config["dexgraspnet"]["root"]:
        catalogs.append(f"{RESULTS}/dexgraspnet/objects/catalog.parquet")
    return catalogs


rule stability_filter:
    input:
        catalogs=stability_catalogs,
    output:
        table=f"{RESULTS}/stability/stability.parquet",
        config=f"{RESULTS}/stability/stability_config.json",
    params:
        cfg=stage_params("seed", "stability", told_hand=False),
        code=code_hash("stability_filter"),
        objects=lambda wildcards, input: " ".join(f"--objects {Path(c).parent}" for c in input.catalogs),
    threads: all_cores()
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/stability_filter.log",
    benchmark:
        f"{LOGS}/benchmarks/stability_filter.tsv"
    shell:
        "dexlite stability-filter --config-json {params.cfg:q} {params.objects} --out {output.table} --record {output.config} "
        "--threads {threads} > {log} 2>&1"
