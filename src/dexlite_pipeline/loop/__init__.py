"""The data loop (Dex1B's): rounds that sample with the last model, keep the new distinct grasps that hold, and retrain."""
