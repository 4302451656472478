"""What the report page shows (``ReportInputs``) and how it is read from the evaluation's files
(``EvaluationFiles``, ``load_report_inputs``), kept apart from the drawing so that the parts of the
page take one object and reading stays in one place.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from dexlite_pipeline.io.grasp_store import GraspSet


@dataclass
class ReportInputs:
    """Everything the page shows; frames are pandas DataFrames (may be empty)."""

    metrics: object
    per_object: object
    convergence: object
    history: object | None
    simulated: GraspSet | None
    lift_config: Mapping = field(default_factory=dict)
    objects_dirs: Sequence[str] = ()
    rendered_per_method: int = 2
    config: Mapping = field(default_factory=dict)  # the whole run config, shown in the page
    title: str = "DexLite evaluation"
    csv_links: Mapping[str, str] = field(default_factory=dict)  # CSV file name -> link relative to the page
    budget: object | None = None  # budget.csv: lift success after each post-optimization budget (optional)
    seed: int = 0  # seeds the random choice of pictured grasps
    learning_curve: object | None = None  # the shipped model's learning curve (docs/learning_curve.csv; optional)
    run_facts: Sequence[tuple[str, str]] = ()  # (label, value): report date, code commit, wall time, machine (report.run_facts)
    data_loop: object | None = None  # the data loop's table, a row per round (results/loop.csv; optional)


@dataclass(frozen=True)
class EvaluationFiles:
    """The evaluation's outputs the report reads (budget and record may be absent or empty)."""

    metrics: str
    per_object: str
    convergence: str
    budget: str | None = None
    record: str | None = None

    def tables(self) -> dict[str, str]:
        """Link name (the file name) -> path of each table that exists."""
        paths = (self.metrics, self.per_object, self.convergence, self.budget)
        return {Path(p).name: p for p in paths if p and Path(p).is_file()}


def load_report_inputs(files: EvaluationFiles, sim_paths: list[str], history_path: str | None, objects_dirs: list[str],
                       config: dict, page_path: str, learning_curve_path: str | None = None, benchmarks_dir: str | None = None,
                       loop_path: str | None = None) -> ReportInputs:
    """Everything the page shows, read from the evaluation's files; CSV links relative to the page's folder.

    ``benchmarks_dir``: the run's job benchmark files (logs/benchmarks), for the wall time at the top;
    ``loop_path``: the data loop's table (results/loop.csv), when the run had the loop.
    """
    import json
    import os

    import pandas as pd

    from dexlite_pipeline.evaluation.protocol import evaluate_config_from
    from dexlite_pipeline.evaluation.step_keys import REPORT_KEYS
    from dexlite_pipeline.report.run_facts import run_facts
    from dexlite_pipeline.settings import build_config

    for path in (files.metrics, files.per_object, files.convergence):
        if not Path(path).is_file():
            raise FileNotFoundError(f"{path}: evaluation output missing (run dexlite evaluate --step aggregate)")
    record = json.loads(Path(files.record).read_text()) if files.record and Path(files.record).is_file() else {}
    budget = pd.read_csv(files.budget) if files.budget and Path(files.budget).is_file() and Path(files.budget).stat().st_size else None
    history = pd.read_csv(history_path) if history_path and Path(history_path).is_file() else None
    page_dir = Path(page_path).parent
    return ReportInputs(
        metrics=pd.read_csv(files.metrics),
        per_object=pd.read_csv(files.per_object),
        convergence=pd.read_csv(files.convergence),
        history=history,
        simulated=simulated_with_hand(sim_paths),
        lift_config=record.get("lift_config") or {},
        objects_dirs=objects_dirs,
        rendered_per_method=evaluate_config_from(config, REPORT_KEYS).rendered_per_method,
        config=config,
        csv_links={name: Path(os.path.relpath(path, page_dir)).as_posix() for name, path in files.tables().items()},
        seed=build_config(config).seed,
        budget=budget,
        learning_curve=pd.read_csv(learning_curve_path) if learning_curve_path else None,
        run_facts=run_facts(config, benchmarks_dir),
        data_loop=pd.read_csv(loop_path) if loop_path else None,
    )


def simulated_with_hand(sim_paths: list[str]):
    """The evaluation's simulated shards as one set (``concatenate_shards``; None when none holds grasps) whose attributes
    are the hand record the shards share (``hand``, ``joint_names``: what the pictures and the 3-D view draw);
    ``GraspStoreError`` in one line when two shards are of different hands."""
    from dexlite_pipeline.evaluation.tables import concatenate_shards
    from dexlite_pipeline.io.grasp_store import check_one_hand, read_grasp_store

    shards = [read_grasp_store(p) for p in sim_paths]
    simulated = concatenate_shards(shards)
    if simulated is not None:
        simulated.attrs.update(check_one_hand([(str(p), s.attrs) for p, s in zip(sim_paths, shards)]))
    return simulated
