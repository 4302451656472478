"""Process-pool map that survives bad inputs: one item's failure never stops the others.

Python exceptions become per-item error results. A worker that dies outright (a segfault in
a native library, an out-of-memory kill) breaks a ``ProcessPoolExecutor`` and fails every
pending future; the items left unfinished are then re-run one per fresh single-worker
process, so the item that kills its worker is identified and reported, and the rest finish.

A worker ends with the process that started it: a stage killed by Snakemake, by a scheduler or by hand (SIGTERM,
SIGKILL) would otherwise leave its workers running, each on a core, until their items are done. Each worker checks
every ``PARENT_CHECK_S`` seconds that its parent is still the process that started it, and exits at once when not.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import TypeVar

log = logging.getLogger(__name__)

T = TypeVar("T")
R = TypeVar("R")

PARENT_CHECK_S = 1.0  # how often a worker checks that the process that started it still runs (seconds)
ORPHAN_EXIT_STATUS = 3  # a worker's exit status when its parent died


def _exit_with_parent(parent_pid: int, check_s: float = PARENT_CHECK_S) -> None:
    """Start a daemon thread that ends this process (``os._exit``: no cleanup, the parent is gone) once its parent is no
    longer ``parent_pid`` (a process whose parent dies is handed to another: init or a subreaper)."""

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(check_s)
        os._exit(ORPHAN_EXIT_STATUS)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def _single_threaded_worker(parent_pid: int) -> None:
    """Each worker owns one core (native libraries spawn no threads of their own) and ends with ``parent_pid``."""
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "IGL_NUM_THREADS"):
        os.environ[name] = "1"
    _exit_with_parent(parent_pid)


def _pool(workers: int) -> ProcessPoolExecutor:
    """``workers`` spawned single-threaded worker processes that end with this process."""
    context = multiprocessing.get_context("spawn")
    return ProcessPoolExecutor(workers, mp_context=context, initializer=_single_threaded_worker, initargs=(os.getpid(),))


def _run_isolated(func: Callable[[T], R], item: T, on_error: Callable[[T, str], R]) -> R:
    with _pool(1) as pool:
        try:
            return pool.submit(func, item).result()
        except BrokenProcessPool:
            return on_error(item, "worker process crashed (native library failure or out of memory)")
        except Exception as exc:  # noqa: BLE001 - any failure of one item is that item's result
            return on_error(item, f"{type(exc).__name__}: {exc}")


def resilient_map(
    func: Callable[[T], R],
    items: Sequence[T],
    workers: int,
    on_error: Callable[[T, str], R],
    finished: Callable[[int], None] | None = None,
) -> list[R]:
    """``[func(item) for item in items]`` over ``workers`` processes, in item order.

    ``func`` must be picklable (a module-level function or a ``functools.partial`` of one).
    ``on_error(item, message)`` builds the result of an item whose call raised or crashed.
    ``finished(index)`` is called in this process as each item ends (its index in ``items``), for progress lines.
    ``workers <= 0`` runs in this process (no crash isolation; for tests and debugging).
    """
    results: list[R | None] = [None] * len(items)
    done = [False] * len(items)
    if workers <= 0:
        for i, item in enumerate(items):
            try:
                results[i] = func(item)
            except Exception as exc:  # noqa: BLE001
                results[i] = on_error(item, f"{type(exc).__name__}: {exc}")
            if finished:
                finished(i)
        return results  # type: ignore[return-value]
    with _pool(min(workers, max(1, len(items)))) as pool:
        futures = {pool.submit(func, item): i for i, item in enumerate(items)}
        for future in as_completed(futures):
            i = futures[future]
            try:
                results[i] = future.result()
            except BrokenProcessPool:
                continue
            except Exception as exc:  # noqa: BLE001
                results[i] = on_error(items[i], f"{type(exc).__name__}: {exc}")
            done[i] = True
            if finished:
                finished(i)
    leftover = [i for i, ok in enumerate(done) if not ok]
    if leftover:
        log.warning("a worker process crashed; re-running %d unfinished item(s) one per process", len(leftover))
    for i in leftover:
        results[i] = _run_isolated(func, items[i], on_error)
        if finished:
            finished(i)
    return results  # type: ignore[return-value]
