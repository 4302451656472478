"""Checks on prepared assets shared by the import tests."""

from __future__ import annotations

import numpy as np


def assert_sdf_sign_matches_pieces(asset, soup, rng: np.random.Generator, samples: int = 2000) -> None:
    """The asset's signed distance grid is positive exactly inside the union of the convex pieces ``soup``
    (a trimesh of the decomposed mesh), at grid points away from the surface (|d| > 1e-3)."""
    import igl

    idx = rng.integers(0, asset.sdf.shape[0], size=(samples, 3))
    points = asset.grid_min + idx * asset.voxel_size
    values = asset.sdf[idx[:, 0], idx[:, 1], idx[:, 2]]
    inside_some_piece = igl.winding_number(np.asarray(soup.vertices), np.asarray(soup.faces), points) > 0.5
    clear = np.abs(values) > 1e-3  # away from the surface
    assert inside_some_piece.any() and (~inside_some_piece).any()
    np.testing.assert_array_equal(values[clear] > 0, inside_some_piece[clear])
