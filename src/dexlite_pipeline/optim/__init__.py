"""The annealed RMSProp-style grasp optimizer (seed synthesis and post-optimization)."""
