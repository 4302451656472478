"""DexLite: staged, reproducible dexterous-grasp synthesis for the Shadow Hand."""

__version__ = "0.1.0"

_API = ("grasp", "GraspResult", "MeshGrasps")


def __getattr__(name: str):
    """``dexlite_pipeline.grasp`` and its result types (``dexlite_pipeline.api``), imported on first use: the stages
    import this package and need none of it."""
    if name in _API:
        from dexlite_pipeline import api

        return getattr(api, name)
    raise AttributeError(f"module 'dexlite_pipeline' has no attribute {name!r}")
