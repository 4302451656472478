"""Crash-tolerant process map: exceptions and dead workers become per-item results; workers end with their parent."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from dexlite_pipeline.parallel import PARENT_CHECK_S, resilient_map


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


@pytest.mark.parametrize("workers, items", [(0, [1, 2, 3, 4]), (2, [1, 2, 3, 4, 5, 6])])  # in a pool, 5 crashes its worker
def test_every_item_is_reported_finished_once(workers, items):
    finished = []
    resilient_map(square_or_fail, items, workers, error_result, finished.append)
    assert sorted(finished) == list(range(len(items)))


def test_a_crashing_worker_fails_only_its_item():
    results = resilient_map(square_or_fail, [1, 2, 3, 4, 5, 6], 2, error_result)
    assert results[:5] == [1, 4, "3: ValueError: three is bad", 16, "5: worker process crashed (native library failure or out of memory)"]
    assert results[5] == 36


def _children(pid: int) -> set[int]:
    """The live child processes of ``pid`` (Linux /proc)."""
    from pathlib import Path

    found = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            found |= {int(c) for c in (task / "children").read_text().split()}
        except OSError:
            continue
    return found


def _command_line(pid: int) -> str:
    """The command line of ``pid`` ('' once it has exited)."""
    try:
        with open(f"/proc/{pid}/cmdline") as file:
            return file.read()
    except OSError:
        return ""


def _running(pid: int) -> bool:
    """Whether ``pid`` exists and is not a zombie (an exited process its new parent has not reaped yet)."""
    from pathlib import Path

    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_end_when_the_process_that_started_them_is_killed():
    script = ("import time\nfrom dexlite_pipeline.parallel import resilient_map\n"
              "resilient_map(time.sleep, [120.0, 120.0], 2, lambda item, message: message)\n")  # fmt: skip
    parent = subprocess.Popen([sys.executable, "-c", script])
    workers: set[int] = set()
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and len(workers) < 2:  # the two workers, each sleeping in its item
            workers = {c for c in _children(parent.pid) if "spawn_main" in _command_line(c)}
            time.sleep(0.2)
        assert len(workers) == 2, "the pool's workers did not start"
        time.sleep(1.0)  # past the workers' initializer
        parent.kill()
        parent.wait()
        deadline = time.monotonic() + 3 * PARENT_CHECK_S + 5
        while time.monotonic() < deadline and any(_running(w) for w in workers):
            time.sleep(0.2)
        assert not any(_running(w) for w in workers), "a worker outlived the process that started it"
    finally:
        parent.kill()
        for w in workers:
            if _running(w):
                os.kill(w, 9)
