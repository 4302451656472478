# DexLite pipeline: this file only wires the stages together (see workflow/rules/).
configfile: "config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/prepare_objects.smk"
include: "workflow/rules/stability_filter.smk"
include: "workflow/rules/optimize_grasps.smk"
include: "workflow/rules/import_dexgraspnet.smk"
include: "workflow/rules/dataset_grasps.smk"
include: "workflow/rules/curate.smk"
include: "workflow/rules/train_cvae.smk"
include: "workflow/rules/lift_validate.smk"
include: "workflow/rules/loop.smk"
include: "workflow/rules/evaluator.smk"
include: "workflow/rules/sample_grasps.smk"
include: "workflow/rules/post_optimize.smk"
include: "workflow/rules/evaluate.smk"
include: "workflow/rules/model_batch.smk"


localrules:
    all,
    model_batch_all,


rule all:
    input:
        default_outputs,  # final_outputs(), with any hand (config key hand)
    default_target: True


rule model_batch_all:
    """Every shard of a model-made dataset batch (workflow/rules/model_batch.smk)."""
    input:
        model_batch_outputs(),
