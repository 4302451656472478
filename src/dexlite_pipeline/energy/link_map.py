"""Fixed link-frame points and frames mapped to the object frame by one matrix product.

Gathering each point's (3, 3) link rotation and multiplying by broadcasting moves nine
floats per point through several temporaries; on a CPU that dominated the energy.
Instead, every output coordinate is a fixed linear function of the link frames, so the
map is one dense (L·12, P·K) matrix and the whole batch is a single GEMM (and so is its
gradient).
"""

from __future__ import annotations

import torch

from dexlite_pipeline.hand.model import HandFrames


class LinkFrameMap:
    """Maps (B, L) link frames to (B, P, 3, K) outputs: each row's link frame [R | t] times a fixed (4, K) offset.

    A point x is the offset [x; 1] (K = 1); a rigidly attached frame [Rₛ | cₛ] is the
    offset [[Rₛ, cₛ], [0, 1]] (K = 4, output [R·Rₛ | R·cₛ + t]).
    """

    def __init__(self, offsets: torch.Tensor, link: torch.Tensor, link_count: int) -> None:
        count, _, width = offsets.shape
        matrix = offsets.new_zeros(link_count, 3, 4, count, 3, width)
        rows = torch.arange(count, device=offsets.device)
        for i in range(3):
            matrix[link, i, :, rows, i, :] = offsets
        self.matrix = matrix.reshape(link_count * 12, count * 3 * width)
        self.shape = (count, 3, width)
        self.offsets = offsets
        self.link = link
        self._matrix_t: torch.Tensor | None = None

    @classmethod
    def for_points(cls, points_local: torch.Tensor, link: torch.Tensor, link_count: int) -> "LinkFrameMap":
        homogeneous = torch.cat([points_local, torch.ones_like(points_local[:, :1])], dim=1)
        return cls(homogeneous[:, :, None], link, link_count)

    @classmethod
    def for_frames(cls, rotation: torch.Tensor, position: torch.Tensor, link: torch.Tensor, link_count: int) -> "LinkFrameMap":
        offsets = torch.zeros(len(rotation), 4, 4, dtype=rotation.dtype, device=rotation.device)
        offsets[:, :3, :3] = rotation
        offsets[:, :3, 3] = position
        offsets[:, 3, 3] = 1.0
        return cls(offsets, link, link_count)

    def __call__(self, frames: HandFrames) -> torch.Tensor:
        batch = frames.translation.shape[0]
        flat = torch.cat([frames.rotation, frames.translation[..., None]], dim=-1).reshape(batch, self.matrix.shape[0])
        out = (flat @ self.matrix).reshape(batch, *self.shape)
        return out[..., 0] if self.shape[2] == 1 else out

    def transposed(self, frames: HandFrames) -> torch.Tensor:
        """The outputs laid out (P, 3, B) or (P, 3, 4, B): each row's values for all grasps are contiguous.

        Selecting rows (``index_select`` on dim 0) is then a plain copy of contiguous blocks,
        several times faster than gathering along dim 1 of the (B, P, 3) layout.
        """
        if self._matrix_t is None:
            self._matrix_t = self.matrix.T.contiguous()
        batch = frames.translation.shape[0]
        flat = torch.cat([frames.rotation, frames.translation[..., None]], dim=-1).reshape(batch, self.matrix.shape[0])
        out = (self._matrix_t @ flat.T).reshape(*self.shape, batch)
        return out[:, :, 0] if self.shape[2] == 1 else out

    def rows(self, frames: HandFrames, batch_index: torch.Tensor, row_index: torch.Tensor) -> torch.Tensor:
        """Only the outputs (N, 3) or (N, 3, 4) of the listed (grasp, row) pairs.

        For the few points or frames whose gradient is needed (e.g. those found inside the
        object without autograd): differentiating the dense product instead would push
        the gradient of every row of every grasp back through the GEMM.
        """
        link = self.link[row_index]
        frame = torch.cat([frames.rotation[batch_index, link], frames.translation[batch_index, link][..., None]], dim=-1)  # (N, 3, 4)
        out = frame @ self.offsets[row_index]  # (N, 4, K) offsets
        return out[..., 0] if self.shape[2] == 1 else out
