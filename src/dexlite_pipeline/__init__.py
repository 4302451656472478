"""DexLite: staged, reproducible dexterous-grasp synthesis for the Shadow Hand."""

__version__ = "0.1.0"
