"""Random draws that belong to a grasp, not to its place in a batch (counter-based, splitmix64).

A torch generator hands out numbers in batch order, so the same grasp draws different numbers
beside different grasps, and a stage could not cut its work into other batches (across shards,
parts or objects) without changing results. Here every draw is a hash of (run seed, grasp key,
iteration, stream, index): a grasp with the same key and seed draws the same numbers alone or in
any batch. splitmix64 (Steele, Lea and Flood, 2014) mixes the counter; its top 53 bits give a
uniform double in [0, 1).
"""

from __future__ import annotations

import numpy as np
import torch

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX_1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX_2 = np.uint64(0x94D049BB133111EB)


def _splitmix64(x: np.ndarray) -> np.ndarray:
    """splitmix64's output for counters ``x`` (uint64, any shape); arithmetic wraps modulo 2⁶⁴."""
    with np.errstate(over="ignore"):
        z = x + _GOLDEN
        z = (z ^ (z >> np.uint64(30))) * _MIX_1
        z = (z ^ (z >> np.uint64(27))) * _MIX_2
        return z ^ (z >> np.uint64(31))


class GraspRandom:
    """Uniform draws per grasp, keyed by ``keys`` (B,) non-negative integers and the run's ``seed``."""

    # Streams: what each draw is for, so two purposes never share numbers.
    INITIAL_CONTACTS, SWITCH, REDRAW, ACCEPT, CONTACT_SEARCH = range(5)

    def __init__(self, seed: int, keys: torch.Tensor) -> None:
        keys = np.asarray(keys.cpu().numpy() if isinstance(keys, torch.Tensor) else keys, dtype=np.int64)
        if (keys < 0).any():
            raise ValueError("grasp keys must be non-negative")
        self.keys = keys.astype(np.uint64)
        self.seed = _splitmix64(np.asarray([seed & 0xFFFFFFFFFFFFFFFF], dtype=np.uint64))[0]

    def take(self, rows: torch.Tensor) -> "GraspRandom":
        """The streams of the grasps at ``rows`` (each keeps its own numbers)."""
        taken = object.__new__(GraspRandom)
        taken.keys, taken.seed = self.keys[rows.cpu().numpy()], self.seed
        return taken

    def uniform(self, iteration: int, stream: int, count: int) -> torch.Tensor:
        """(B, count) float64 uniforms in [0, 1) for ``iteration`` and ``stream``."""
        with np.errstate(over="ignore"):
            head = _splitmix64(self.seed ^ _splitmix64(self.keys * np.uint64(0x100000001B3) + np.uint64(iteration)))
            head = _splitmix64(head + np.uint64(stream) * _GOLDEN)
            bits = _splitmix64(head[:, None] + np.arange(count, dtype=np.uint64)[None, :] * _MIX_1)
        return torch.from_numpy((bits >> np.uint64(11)).astype(np.float64) * (1.0 / (1 << 53)))

    def integers(self, high: int, iteration: int, stream: int, count: int) -> torch.Tensor:
        """(B, count) int64 uniform in [0, high)."""
        return (self.uniform(iteration, stream, count) * high).long().clamp(max=high - 1)

    def weighted(self, weight: torch.Tensor, iteration: int, stream: int, count: int) -> torch.Tensor:
        """(B, count) indices drawn with replacement ∝ ``weight`` (B, N) ≥ 0 (inverse CDF, as ``torch.multinomial``).

        Weights (B, S, N), one row per slot (``ContactSlots``), give (B, S, count): each grasp draws S·count uniforms.
        """
        cumulative = weight.double().cumsum(dim=-1)
        uniform = self.uniform(iteration, stream, count * (weight.shape[1] if weight.ndim == 3 else 1)).reshape(*weight.shape[:-1], count)
        target = uniform * cumulative[..., -1:]
        return torch.searchsorted(cumulative, target, right=True).clamp(max=weight.shape[-1] - 1)
