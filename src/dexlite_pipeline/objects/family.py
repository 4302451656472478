"""Which family an object id belongs to, read from the id alone (no mesh code: the trainer and the report use it).

A generated household object is ``household-<family>-<NNN>`` or, perturbed, ``household-<family>-<NNN>-p<k>``
(``objects.household``): its family, its perturbed instances with it. pybullet_data's procedural objects
(``pb-random-NNN``) are one family, ``procedural``; every other id (a user's files, pybullet_data's named objects,
DexGraspNet imports) is ``other``.
"""

from __future__ import annotations

HOUSEHOLD_PREFIX = "household-"
PROCEDURAL_PREFIX = "pb-random-"


def object_family(object_id: str) -> str:
    """The family of ``object_id`` (module docstring)."""
    if object_id.startswith(PROCEDURAL_PREFIX):
        return "procedural"
    if not object_id.startswith(HOUSEHOLD_PREFIX):
        return "other"
    parts = object_id[len(HOUSEHOLD_PREFIX):].split("-")
    if len(parts) == 3 and parts[2][:1] == "p" and parts[2][1:].isdigit():
        parts = parts[:2]  # a perturbed instance
    return parts[0] if len(parts) == 2 and parts[0] and parts[1].isdigit() else "other"
