"""Objects: sources, normalization, convex decomposition, SDF grids, point clouds, stability."""
