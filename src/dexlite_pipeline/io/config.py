"""The DexGraspNet import's config type: section ``dexgraspnet``.

A leaf of the config tree (``settings``): it imports no import code, so a stage's code hash
(``codehash``) covers this shape without the computation (``io.dexgraspnet``).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DexGraspNetConfig:
    """Config section ``dexgraspnet``: where the download is and how its objects are split."""

    root: str = ""  # a DexGraspNet download (dataset/, meshdata/); empty = not used
    heldout_fraction: float = 0.0  # share of imported objects held out for evaluation (seeded, per object code)
    heldout_object_codes: tuple[str, ...] = ()  # object codes always held out
