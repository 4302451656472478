"""Config key ``hand`` made into the hand object the stages use, and the record a grasp store keeps of it.

``resolve_hand("shadow")`` is the built-in ``ShadowHand`` (unchanged: 28-number poses, its own tables), any other
value (``allegro``, ``leap``, the path of an MJCF file) a ``DescribedHand`` (6 + J numbers). ``hand_record`` is what
a store written with the hand records in its attributes (``io.grasp_store``): ``hand`` (the name, or the file's
path as given), ``hand_sha256`` for a file (its bytes: the same hand whatever its path), ``joint_names`` in pose order.
A value that cannot be a hand raises ``HandChoiceError`` with one line naming the key (``hand: VALUE: reason``).
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

from dexlite_pipeline.hand.description import HAND_NAMES, HandDescriptionError, hand_description
from dexlite_pipeline.hand.model import JOINT_NAMES, ShadowHand

SHADOW = "shadow"


class HandChoiceError(ValueError):
    """Config key ``hand`` names no usable hand; the message is one line starting ``hand: VALUE:``."""


def _description(value: str):
    """The ``HandDescription`` of ``value``; ``HandChoiceError`` naming the key when the name or the file is unusable."""
    text = str(value)
    if text not in HAND_NAMES and not Path(text).expanduser().is_file():
        raise HandChoiceError(f"hand: {text}: no such file (a hand is {', '.join(HAND_NAMES)} or the path of an MJCF file)")
    try:
        return hand_description(text if text in HAND_NAMES else str(Path(text).expanduser()))
    except HandDescriptionError as exc:
        reason = str(exc)
        path = str(Path(text).expanduser().resolve())
        reason = reason[len(path) + 2:] if reason.startswith(path + ": ") else reason
        raise HandChoiceError(f"hand: {text}: {reason}") from None


def resolve_hand(value: str, device="cpu"):
    """The hand model for config key ``hand`` on ``device``: ``ShadowHand`` for shadow, else a ``DescribedHand``."""
    if str(value) == SHADOW:
        return ShadowHand(device)
    from dexlite_pipeline.hand.described import DescribedHand

    return DescribedHand(_description(value), device)


def check_hand(value: str) -> None:
    """Raise ``HandChoiceError`` (one line naming the key) when ``value`` cannot be made a hand (before any work)."""
    if str(value) != SHADOW:
        _description(value)


@functools.lru_cache(maxsize=16)
def _file_sha256(path: str, mtime_ns: int, size: int) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def file_sha256(path: str | Path) -> str:
    """SHA-256 (hex) of a hand's MJCF file's bytes."""
    p = Path(path).expanduser().resolve()
    stat = p.stat()
    return _file_sha256(str(p), stat.st_mtime_ns, stat.st_size)


def hand_record(value: str) -> dict:
    """What a grasp store of hand ``value`` records (module doc): ``hand``, ``hand_sha256`` for a file, ``joint_names``."""
    text = str(value)
    if text == SHADOW:
        return {"hand": SHADOW, "joint_names": list(JOINT_NAMES)}
    description = _description(text)
    record = {"hand": text}
    if text not in HAND_NAMES:
        record["hand_sha256"] = file_sha256(text)
    record["joint_names"] = list(description.joint_names)
    return record


__all__ = ["SHADOW", "HandChoiceError", "check_hand", "file_sha256", "hand_record", "resolve_hand"]
