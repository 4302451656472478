"""PointNet + CVAE grasp model: network, training, sampling."""
