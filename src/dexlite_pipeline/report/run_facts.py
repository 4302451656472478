"""Facts about the run a report describes, shown at the top of the page: when, which code, how long, on what.

- report date: when the page was built (UTC);
- code commit: ``git describe --always --tags --dirty`` of the checkout the package runs from,
  'unknown' when that is not a git checkout (an installed package) or git is missing;
- wall time: from the Snakemake benchmark files of the run's jobs (``logs/benchmarks/*.tsv``,
  one per job: its wall seconds ``s`` and ``cpu_time``, written when the job ends): from the
  first job's start (file time minus its wall seconds) to the last job's end, with the jobs'
  summed wall and CPU time. Jobs kept from an earlier invocation count with their own
  times, so a run resumed later spans both. 'not measurable' without benchmark files;
- machine: logical cores, CPU model (/proc/cpuinfo, else the platform's name), torch device.
"""

from __future__ import annotations

import datetime as dt
import os
import platform
import subprocess
from collections.abc import Mapping
from pathlib import Path

import numpy as np

PACKAGE_ROOT = Path(__file__).resolve().parents[3]  # the checkout holding src/dexlite_pipeline (when run from source)


def code_commit(checkout: Path = PACKAGE_ROOT) -> str:
    """``git describe --always --tags --dirty`` of ``checkout``; 'unknown' when it cannot tell."""
    try:
        done = subprocess.run(["git", "-C", str(checkout), "describe", "--always", "--tags", "--dirty"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return done.stdout.strip() if done.returncode == 0 and done.stdout.strip() else "unknown"


def benchmark_times(benchmarks_dir) -> dict | None:
    """Jobs, span from first start to last end (s), summed wall and CPU seconds of the benchmark files; None when there are none."""
    import pandas as pd

    if not benchmarks_dir or not Path(benchmarks_dir).is_dir():
        return None
    starts, ends, wall, cpu = [], [], 0.0, 0.0
    for path in sorted(Path(benchmarks_dir).glob("*.tsv")):
        try:
            table = pd.read_csv(path, sep="\t")
        except (OSError, ValueError):
            continue
        if "s" not in table.columns or not len(table):
            continue
        seconds = float(pd.to_numeric(table["s"], errors="coerce").iloc[-1])
        if not np.isfinite(seconds):
            continue
        end = path.stat().st_mtime
        starts.append(end - seconds)
        ends.append(end)
        wall += seconds
        if "cpu_time" in table.columns:
            value = float(pd.to_numeric(table["cpu_time"], errors="coerce").iloc[-1])
            cpu += value if np.isfinite(value) else 0.0
    if not ends:
        return None
    return {"jobs": len(ends), "span_s": max(ends) - min(starts), "wall_s": wall, "cpu_s": cpu}


def duration_text(seconds: float) -> str:
    """"42 s", "12.5 min", "3.2 h"."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo on Linux), else the platform's processor string, else 'unknown'."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name") and ":" in line:
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def torch_device_text(config: Mapping) -> str:
    """The device the run's config resolves to (``device``: auto = CUDA when present), with the GPU's name."""
    import torch

    from dexlite_pipeline.device import resolve_device
    from dexlite_pipeline.settings import build_config

    configured = build_config(config).device
    try:
        device = resolve_device(configured)
    except (RuntimeError, ValueError) as exc:
        return f"unavailable ({exc})"
    if device.type == "cuda":
        return f"{device} ({torch.cuda.get_device_name(device)})"
    return str(device)


def run_facts(config: Mapping, benchmarks_dir=None, checkout: Path = PACKAGE_ROOT, now: dt.datetime | None = None) -> list[tuple[str, str]]:
    """(label, value) rows: report date, code commit, wall time of the run, machine."""
    now = now or dt.datetime.now(dt.timezone.utc)
    times = benchmark_times(benchmarks_dir)
    if times is None:
        wall = "not measurable (no job benchmark files" + (f" in {benchmarks_dir})" if benchmarks_dir else ")")
    else:
        wall = (f"{duration_text(times['span_s'])} from the first job's start to the last job's end ({times['jobs']} jobs: "
                f"{duration_text(times['wall_s'])} of job wall time, {duration_text(times['cpu_s'])} CPU)")  # fmt: skip
    machine = f"{os.cpu_count() or '?'} logical cores, {cpu_model()}, torch device {torch_device_text(config)}"
    return [
        ("report date", now.strftime("%Y-%m-%d %H:%M UTC")),
        ("code commit", code_commit(checkout)),
        ("wall time of the run", wall),
        ("machine", machine),
    ]
