"""The Shadow Hand: MJCF from gymnasium-robotics, batched kinematics, DexGraspNet qpos."""

from dexlite_pipeline.hand.model import JOINT_NAMES, POSE_DIM, HandFrames, ShadowHand

__all__ = ["JOINT_NAMES", "POSE_DIM", "HandFrames", "ShadowHand"]
