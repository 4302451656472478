"""A throwaway one-node SLURM cluster on loopback for the integration test.

Starts its own munged, slurmctld and slurmd (foreground children, own config, sockets,
spool and state directories under a temporary folder, free ports), waits until the node
is idle, and stops all three on exit, also when the test fails. Nothing under /etc is
touched: clients find the cluster through ``SLURM_CONF``. Inside a job, the executor
plugin starts each rule with ``srun`` after dropping every ``SLURM_*`` variable (so a
real site's /etc/slurm/slurm.conf or configless DNS lookup is what srun uses there); the
test puts an ``srun`` first on PATH that points the real one at the test's config, which
stands in for that site-wide config file. No accounting database; job states come from
``squeue`` (jobs stay visible for ``MinJobAge`` seconds after they end).
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

DAEMONS = ("munged", "slurmctld", "slurmd")
NODE_CPUS = 2


class ClusterUnavailable(RuntimeError):
    """This machine cannot run a local SLURM (no binaries, not root, or a daemon does not start)."""


@dataclass(frozen=True)
class LocalCluster:
    root: Path
    env: dict[str, str]
    partition: str
    node_memory_mb: int

    def run(self, *command: str, timeout_s: float = 30) -> str:
        done = subprocess.run(command, env=self.env, capture_output=True, text=True, timeout=timeout_s)
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(command)} failed: {done.stderr.strip()}")
        return done.stdout


def missing_requirements() -> str | None:
    """Why a local cluster cannot run here, or None."""
    if os.geteuid() != 0:
        return "not root (slurmd must run as root to launch jobs)"
    absent = [b for b in (*DAEMONS, "sbatch", "squeue", "srun", "sinfo", "scontrol") if shutil.which(b) is None]
    if absent:
        return f"SLURM/munge binaries not installed ({', '.join(absent)}); .ci/run apt-installs slurm-wlm and munge"
    return None


def _free_ports(count: int) -> list[int]:
    sockets = []
    try:
        for _ in range(count):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.bind(("127.0.0.1", 0))
            sockets.append(s)
        return [s.getsockname()[1] for s in sockets]
    finally:
        for s in sockets:
            s.close()


def _machine_memory_mb() -> int:
    return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**20)


def write_slurm_conf(root: Path, munge_socket: Path, ctld_port: int, slurmd_port: int, memory_mb: int) -> Path:
    """A one-node cluster: node ``localhost`` (loopback), partition ``debug``, no accounting."""
    for sub in ("state", "spool", "log"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    conf = root / "slurm.conf"
    conf.write_text(
        "\n".join(
            [
                "ClusterName=dexlite-test",
                "SlurmctldHost=localhost(127.0.0.1)",
                f"SlurmctldPort={ctld_port}",
                f"SlurmdPort={slurmd_port}",
                "SlurmUser=root",
                "SlurmdUser=root",
                "AuthType=auth/munge",
                "CredType=cred/munge",
                f"AuthInfo=socket={munge_socket}",
                f"StateSaveLocation={root / 'state'}",
                f"SlurmdSpoolDir={root / 'spool'}",
                f"SlurmctldPidFile={root / 'slurmctld.pid'}",
                f"SlurmdPidFile={root / 'slurmd.pid'}",
                f"SlurmctldLogFile={root / 'log' / 'slurmctld.log'}",
                f"SlurmdLogFile={root / 'log' / 'slurmd.log'}",
                "SlurmctldDebug=info",
                "SlurmdDebug=info",
                "SelectType=select/cons_tres",
                "SelectTypeParameters=CR_Core_Memory",
                "SchedulerType=sched/backfill",
                "ProctrackType=proctrack/linuxproc",
                "TaskPlugin=task/none",
                "JobAcctGatherType=jobacct_gather/none",
                "AccountingStorageType=accounting_storage/none",
                "JobCompType=jobcomp/none",
                "MpiDefault=none",
                "SwitchType=switch/none",
                "ReturnToService=2",
                "MinJobAge=3600",  # squeue reports finished jobs this long (no accounting DB)
                "SchedulerParameters=sched_interval=1",
                "MessageTimeout=20",
                f"NodeName=localhost NodeAddr=127.0.0.1 CPUs={NODE_CPUS} RealMemory={memory_mb} State=UNKNOWN",
                "PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP",
                "",
            ]
        )
    )
    return conf


def _write_munge_key(path: Path) -> None:
    path.write_bytes(secrets.token_bytes(1024))
    path.chmod(0o400)


def _srun_with_config(root: Path, conf: Path) -> Path:
    """A bin folder holding an ``srun`` that runs the real one with this cluster's config."""
    bin_dir = root / "bin"
    bin_dir.mkdir(exist_ok=True)
    wrapper = bin_dir / "srun"
    wrapper.write_text(f'#!/bin/sh\nSLURM_CONF="{conf}" exec "{shutil.which("srun")}" "$@"\n')
    wrapper.chmod(0o755)
    return bin_dir


def _stop(process: subprocess.Popen) -> None:
    """Stop one daemon we started (its own process group), escalating to SIGKILL."""
    if process.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGTERM)
    try:
        process.wait(timeout=15)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=5)


def _wait_for(check, what: str, timeout_s: float, processes: dict[str, subprocess.Popen], root: Path) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for name, process in processes.items():
            if process.poll() is not None:
                raise ClusterUnavailable(f"{name} exited with {process.returncode}: {_log_tail(root, name)}")
        if check():
            return
        time.sleep(0.3)
    raise ClusterUnavailable(f"timed out after {timeout_s:.0f} s waiting for {what}: {_log_tail(root, 'slurmd')}")


def _log_tail(root: Path, name: str, lines: int = 5) -> str:
    log = root / "log" / f"{name}.log"
    return " | ".join(log.read_text().splitlines()[-lines:]) if log.is_file() else "(no log)"


@contextlib.contextmanager
def local_slurm_cluster(root: Path, start_timeout_s: float = 60) -> Iterator[LocalCluster]:
    """Run munged + slurmctld + slurmd under ``root`` for the duration of the block."""
    reason = missing_requirements()
    if reason:
        raise ClusterUnavailable(reason)
    root.mkdir(parents=True, exist_ok=True)
    (root / "log").mkdir(exist_ok=True)
    munge_socket = root / "munge.socket"
    key = root / "munge.key"
    _write_munge_key(key)
    ctld_port, slurmd_port = _free_ports(2)
    memory_mb = min(8000, _machine_memory_mb() // 2)
    conf = write_slurm_conf(root, munge_socket, ctld_port, slurmd_port, memory_mb)
    env = {k: v for k, v in os.environ.items() if not k.startswith("SLURM_")}
    env["SLURM_CONF"] = str(conf)
    env["PATH"] = f"{_srun_with_config(root, conf)}{os.pathsep}{env.get('PATH', '')}"
    commands = {
        "munged": [
            "munged", "--foreground", "--force", f"--socket={munge_socket}", f"--key-file={key}",
            f"--pid-file={root / 'munged.pid'}", f"--log-file={root / 'log' / 'munged.log'}",
            f"--seed-file={root / 'munged.seed'}",
        ],
        "slurmctld": ["slurmctld", "-D", "-i", "-f", str(conf)],
        "slurmd": ["slurmd", "-D", "-N", "localhost", "-f", str(conf)],
    }
    processes: dict[str, subprocess.Popen] = {}
    try:
        for name in DAEMONS:
            with open(root / "log" / f"{name}.stdout", "wb") as out:
                processes[name] = subprocess.Popen(
                    commands[name], env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True
                )
            if name == "munged":
                _wait_for(munge_socket.exists, "the munge socket", start_timeout_s, processes, root)
        cluster = LocalCluster(root=root, env=env, partition="debug", node_memory_mb=memory_mb)

        def node_idle() -> bool:
            done = subprocess.run(["sinfo", "-h", "-N", "-o", "%T"], env=env, capture_output=True, text=True)
            return done.returncode == 0 and done.stdout.strip() == "idle"

        _wait_for(node_idle, "node localhost to be idle", start_timeout_s, processes, root)
        yield cluster
    finally:
        if "slurmctld" in processes:
            subprocess.run(["scancel", "--full", "--partition", "debug"], env=env, capture_output=True, timeout=30)
        for name in reversed(list(processes)):
            _stop(processes[name])
