"""Hand forward kinematics: the project's ``ShadowHand`` against pytorch-kinematics.

    python benchmarks/timing/bench_kinematics.py             # batches 1/256/1024/4096, 2 and 1 threads
    python benchmarks/timing/bench_kinematics.py --quick     # small sizes, to check it runs
    python benchmarks/timing/bench_kinematics.py --threads 1 --batches 1024

Times the 23 link frames (rotation and translation in the object frame) of a batch of
random hand poses (joints uniform within their limits, palm anywhere) on the CPU, in
float32, for three implementations:

- ``project``: ``ShadowHand.forward`` (``hand.model``);
- ``pk palm-rooted``: pytorch-kinematics on the palm-rooted chain of ``hand.pk_chain``,
  with the palm pose composed onto its frames in torch (as ``forward_parts`` does);
- ``pk floating palm``: pytorch-kinematics with six virtual palm joints above the palm.

Two modes: ``forward`` (input without gradient) and ``forward+backward`` (the gradient of
a fixed random weighting of all frame entries w.r.t. all 28 pose entries, i.e. joint
angles and palm pose, as one optimizer step needs). The implementations are timed in
turn, round after round, so load from other jobs on the shared cores hits all of them
alike; each cell is the median wall time of its rounds (the row note gives the minimum).
``run(quick)`` returns the rows for ``benchmarks/timing/run_all.py``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch

IMPLEMENTATIONS = ("project", "pk palm-rooted", "pk floating palm")
MODES = ("forward", "forward+backward")


def machine_description() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (f"{cpu}; {os.cpu_count()} logical CPUs; torch {torch.__version__}; Python {platform.python_version()}; "
            f"OMP_WAIT_POLICY {os.environ.get('OMP_WAIT_POLICY', 'unset')}")


def random_poses(joint_limits: torch.Tensor, batch: int, seed: int = 0) -> torch.Tensor:
    """(batch, 28) poses: palm within 0.2 m of the origin, any orientation, joints within limits."""
    g = torch.Generator().manual_seed(seed)
    low, high = joint_limits[:, 0], joint_limits[:, 1]
    return torch.cat([
        0.2 * torch.randn(batch, 3, generator=g),
        (2 * torch.rand(batch, 3, generator=g) - 1) * torch.pi,
        low + (high - low) * torch.rand(batch, 22, generator=g),
    ], dim=1)


def step_functions(batch: int, mode: str, hands: dict) -> dict:
    """One closure per implementation computing the frames (and, with backward, the pose gradient)."""
    pose = random_poses(hands["project"].joint_limits, batch)
    g = torch.Generator().manual_seed(1)
    links = len(hands["project"].link_names)
    w_t, w_r = torch.randn(batch, links, 3, generator=g), torch.randn(batch, links, 3, 3, generator=g)

    def make(hand):
        if mode == "forward":
            return lambda: hand.forward(pose)

        def step():
            x = pose.clone().requires_grad_(True)
            frames = hand.forward(x)
            return torch.autograd.grad((frames.translation * w_t).sum() + (frames.rotation * w_r).sum(), x)[0]

        return step

    return {name: make(hand) for name, hand in hands.items()}


def time_round_robin(steps: dict, min_seconds: float, min_rounds: int, max_rounds: int) -> dict[str, list[float]]:
    """Wall times (s) of each step, run in turn until each has ``min_seconds`` or ``max_rounds``."""
    for step in steps.values():  # warm-up
        step()
        step()
    times = {name: [] for name in steps}
    while True:
        for name, step in steps.items():
            start = time.perf_counter()
            step()
            times[name].append(time.perf_counter() - start)
        rounds = len(next(iter(times.values())))
        if rounds >= max_rounds or (rounds >= min_rounds and min(sum(t) for t in times.values()) >= min_seconds):
            return times


def run(quick: bool = False, batches=None, thread_counts=(2, 1)) -> list[dict]:
    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.hand.pk_chain import PkShadowHand

    batches = batches or ((1, 256) if quick else (1, 256, 1024, 4096))
    hands = {"project": ShadowHand(), "pk palm-rooted": PkShadowHand(), "pk floating palm": PkShadowHand(floating_palm=True)}
    previous = torch.get_num_threads()
    rows = []
    for threads in thread_counts:
        torch.set_num_threads(threads)
        for batch in batches:
            for mode in MODES:
                load = os.getloadavg()[0]
                times = time_round_robin(step_functions(batch, mode, hands), 0.1 if quick else 1.0, 3 if quick else 10, 20 if quick else 500)
                base = float(np.median(times["project"]))
                for name in IMPLEMENTATIONS:
                    median = float(np.median(times[name]))
                    rows.append({
                        "benchmark": f"hand FK {mode}, {threads} thread{'s' if threads > 1 else ''}",
                        "size": f"batch {batch}",
                        "value": 1000 * median,
                        "unit": "ms (wall, median)",
                        "note": f"{name}; {median / base:.2f}x project; min {1000 * min(times[name]):.3f} ms; "
                        f"{len(times[name])} rounds; load avg {max(load, os.getloadavg()[0]):.1f}",
                        "implementation": name, "threads": threads, "batch": batch, "mode": mode,
                    })
    torch.set_num_threads(previous)
    return rows


def format_table(rows: list[dict]) -> str:
    """One line per (threads, batch, mode): the three medians and pytorch-kinematics' best time over the project's."""
    header = ["threads", "batch", "mode", *(f"{n} (ms)" for n in IMPLEMENTATIONS), "best pk / project"]
    cells = {}
    for r in rows:
        cells.setdefault((r["threads"], r["batch"], r["mode"]), {})[r["implementation"]] = r["value"]
    lines = [header]
    for (threads, batch, mode), ms in cells.items():
        best_pk = min(ms["pk palm-rooted"], ms["pk floating palm"])
        lines.append([str(threads), str(batch), mode, *(f"{ms[n]:.3f}" for n in IMPLEMENTATIONS), f"{best_pk / ms['project']:.2f}x"])
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    out = ["| " + " | ".join(c.ljust(w) for c, w in zip(line, widths)) + " |" for line in lines]
    out.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (seconds)")
    parser.add_argument("--batches", type=int, nargs="+", help="batch sizes (default 1 256 1024 4096)")
    parser.add_argument("--threads", type=int, nargs="+", default=[2, 1], help="torch thread counts (default 2 1)")
    args = parser.parse_args()
    print(f"Machine: {machine_description()}")
    rows = run(args.quick, args.batches, tuple(args.threads))
    print(format_table(rows))
    print(f"load average at the end: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
