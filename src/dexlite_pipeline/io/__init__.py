"""Reading and writing the pipeline's data: atomic outputs and Zarr grasp stores."""
