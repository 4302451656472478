"""Reading and writing the pipeline's data: Zarr grasp stores and DexGraspNet files (atomic writes: ``dexlite_pipeline.atomic``)."""
