"""Crash-tolerant process map: exceptions and dead workers become per-item results."""

from __future__ import annotations

import os

from dexlite_pipeline.parallel import resilient_map


def square_or_fail(x: int) -> int:
    if x == 3:
        raise ValueError("three is bad")
    if x == 5:
        os.abort()  # the worker process dies, as in a native-library segfault
    return x * x


def error_result(x: int, message: str) -> str:
    return f"{x}: {message}"


def test_in_process_map_turns_exceptions_into_results():
    assert resilient_map(square_or_fail, [1, 2, 3, 4], 0, error_result) == [1, 4, "3: ValueError: three is bad", 16]


def test_a_crashing_worker_fails_only_its_item():
    results = resilient_map(square_or_fail, [1, 2, 3, 4, 5, 6], 2, error_result)
    assert results[:5] == [1, 4, "3: ValueError: three is bad", 16, "5: worker process crashed (native library failure or out of memory)"]
    assert results[5] == 36
