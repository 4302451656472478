"""The annealed RMSProp-style grasp optimizer (seed synthesis and post-optimization)."""

from dexlite_pipeline.optim.annealing import AnnealingConfig, AnnealingSchedule, OptimizationResult, optimize, pose_to_state, state_to_pose
from dexlite_pipeline.optim.init import HullSampler, InitConfig, initial_poses

__all__ = [
    "AnnealingConfig",
    "AnnealingSchedule",
    "HullSampler",
    "InitConfig",
    "OptimizationResult",
    "initial_poses",
    "optimize",
    "pose_to_state",
    "state_to_pose",
]
