"""User tools built on the pipeline's library (``dexlite grasp``)."""
