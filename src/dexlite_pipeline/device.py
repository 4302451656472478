"""Device and thread selection: ``device: auto`` uses CUDA when present, else the CPU."""

from __future__ import annotations

import torch


def resolve_device(name: str = "auto") -> torch.device:
    """'auto' -> cuda if available else cpu; 'cpu' / 'cuda' / 'cuda:N' as given (checked)."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    device = torch.device(name)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise RuntimeError(f"device {name!r} requested but CUDA is not available (torch {torch.__version__})")
    return device


def set_threads(threads: int | None) -> None:
    """Use exactly the threads the scheduler gave this job (Snakemake's ``threads``)."""
    if threads and threads > 0:
        torch.set_num_threads(int(threads))
        try:
            torch.set_num_interop_threads(max(1, int(threads)))
        except RuntimeError:
            pass  # inter-op threads can be set only once, before any parallel work
