"""Grasp-type conditioning of the CVAE: the types a model knows, the plan of types asked of it, and its refusals.

A model trained on grasps of several types (``grasp_type`` of the training stores, ``power`` where a store has none)
is conditioned on the type: a one-hot over its *vocabulary* (the training grasps' types, sorted by name) is appended
to the encoder's and the decoder's condition (``network.GraspCVAE``), so one model learns the mix and can be asked for
one type. A model trained on one type reads no type input (the one-hot would be constant), and its vocabulary is that
type; a checkpoint written before grasp types existed has no vocabulary and knows power grasps only, the only type
optimization then made.

Sampling asks for ``sample.grasp_type``: ``any`` deals each object's grasps to the vocabulary in the proportions of
the model's training codes, or equally with ``sample.type_mix`` even (a fixed interleaved plan, as optimization from
scratch deals its starts), a type name asks for that type only; a type the model does not know is refused.
"""

from __future__ import annotations

import numpy as np

from dexlite_pipeline.io.grasp_store import DEFAULT_GRASP_TYPE
from dexlite_pipeline.model.config import ANY_GRASP_TYPE, TRAINING_TYPE_MIX


class GraspTypeRequestError(ValueError):
    """A grasp type the model cannot be asked for (the message is one line)."""


def vocabulary_of(types) -> tuple[str, ...]:
    """The distinct grasp types of ``types`` (strings), sorted by name: a model's one-hot columns."""
    return tuple(sorted({str(t) for t in types}))


def known_types(vocabulary: tuple[str, ...]) -> tuple[str, ...]:
    """The types a model with ``vocabulary`` can make: the vocabulary, or power for a model trained before types."""
    return tuple(vocabulary) or (DEFAULT_GRASP_TYPE,)


def type_codes(types, vocabulary: tuple[str, ...]) -> np.ndarray:
    """(N,) int64 each type's column in ``vocabulary`` (a model without one: every type must be power, code 0)."""
    known = known_types(vocabulary)
    names = [str(t) for t in types]
    unknown = sorted(set(names) - set(known))
    if unknown:
        raise GraspTypeRequestError(f"grasp type(s) {', '.join(unknown)} not among the model's types ({', '.join(known)})")
    return np.asarray([known.index(t) for t in names], dtype=np.int64)


def interleaved_plan(share: np.ndarray, count: int) -> np.ndarray:
    """(count,) indices into ``share`` (weights ≥ 0 summing to 1) for ``count`` consecutive items.

    Item j takes the index furthest behind its share of the first j + 1 items (ties: the lower index), so the indices
    are interleaved and every prefix holds each within one item of its share: a mix as a fixed plan, not a draw.
    """
    share = np.asarray(share, dtype=np.float64)
    assigned = np.zeros(len(share))
    out = np.empty(count, dtype=np.int64)
    for j in range(count):
        pick = int(np.argmax((j + 1) * share - assigned))
        assigned[pick] += 1
        out[j] = pick
    return out


def training_mix(code_types: np.ndarray, vocabulary: tuple[str, ...]) -> np.ndarray:
    """(T,) the share of each known type among a model's training codes (``code_types`` their columns); a model without
    codes: equal shares."""
    size = len(known_types(vocabulary))
    counts = np.bincount(np.asarray(code_types, dtype=np.int64), minlength=size)[:size].astype(np.float64)
    return counts / counts.sum() if counts.sum() > 0 else np.full(size, 1.0 / size)


def refusal(vocabulary: tuple[str, ...], request: str) -> str:
    """Why a model with ``vocabulary`` cannot be asked for ``request`` ('' when it can)."""
    known = known_types(vocabulary)
    if request == ANY_GRASP_TYPE or request in known:
        return ""
    how = "it was trained without grasp types" if not vocabulary else "it was trained on no grasp of that type"
    return f"the model knows only {', '.join(known)} grasps ({how}); it cannot make {request} grasps"


def requested_codes(vocabulary: tuple[str, ...], code_types: np.ndarray, request: str, count: int,
                    mix: str = TRAINING_TYPE_MIX) -> np.ndarray:
    """(count,) the type columns of an object's ``count`` sampled grasps: for ``any`` a plan in the training mix's
    proportions (``mix`` training) or every known type equally (``mix`` even), else the requested type's column;
    ``GraspTypeRequestError`` (``refusal``) for a type the model does not know."""
    reason = refusal(vocabulary, request)
    if reason:
        raise GraspTypeRequestError(reason)
    if request == ANY_GRASP_TYPE:
        size = len(known_types(vocabulary))
        share = training_mix(code_types, vocabulary) if mix == TRAINING_TYPE_MIX else np.full(size, 1.0 / size)
        return interleaved_plan(share, count)
    return np.full(count, known_types(vocabulary).index(request), dtype=np.int64)
