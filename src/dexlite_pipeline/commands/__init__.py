"""The user tools' commands (``dexlite energy``, ``lift-test``, ``render``, ``export-dexgraspnet``,
``grasp``): thin argument adapters over the library, as ``stages`` is for the pipeline's stages."""
