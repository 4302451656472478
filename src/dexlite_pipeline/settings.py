"""The typed configuration tree: one class per section of ``config.yaml``, one root that holds them.

``PipelineConfig`` mirrors the file section by section; each section's class lives with the
component it configures (``objects.config.ObjectsConfig``, ``sim.config.LiftConfig``, ...)
and shared shapes are one type wherever they appear: ``EnergyWeights`` (``energy.weights``,
``train.energy_weights``, ``post_optimize.energy_weights``), ``AnnealingSchedule``
(``optimize_grasps.annealing``, ``post_optimize.annealing``), ``EnergyThresholds``
(``optimize_grasps.thresholds``, ``curate.thresholds``) and ``InitConfig`` (``optimize_grasps.init``,
``post_optimize.random_init``). The dataclass defaults are the defaults: ``config.yaml`` lists
the same values so that the file documents every key (``tests/test_config.py`` holds the
classes, the schema and the file to each other).

The section classes live in leaf modules (each component's ``config`` module) that import no
pipeline code but ``dexlite_pipeline.config`` and each other: a stage imports this tree without importing other components' code, so its code hash
(``codehash``) covers only the code it runs (docs/design.md, "Code hashes").
"""

from __future__ import annotations

from dataclasses import dataclass, field

from dexlite_pipeline.config import ConfigError, from_section, parse_config_json, retired_keys_message
from dexlite_pipeline.curation.config import CurateConfig
from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.evaluation.config import DiversityConfig, EvaluateConfig
from dexlite_pipeline.io.config import DexGraspNetConfig
from dexlite_pipeline.loop.config import LoopConfig
from dexlite_pipeline.model.config import SampleConfig, TrainConfig
from dexlite_pipeline.objects.config import ObjectsConfig, StabilityConfig
from dexlite_pipeline.optim.config import OptimizeGraspsConfig, PostOptimizeConfig
from dexlite_pipeline.sim.config import LiftConfig, SceneConfig


@dataclass(frozen=True)
class PipelineConfig:
    """The whole of ``config.yaml``."""

    seed: int = 0  # global random seed; every stage derives its own from it
    device: str = "auto"  # auto (CUDA when present, else CPU), cpu, cuda, cuda:N
    shards: int = 2  # grasp-heavy stages split objects into this many groups
    objects: ObjectsConfig = field(default_factory=ObjectsConfig)
    dexgraspnet: DexGraspNetConfig = field(default_factory=DexGraspNetConfig)
    diversity: DiversityConfig = field(default_factory=DiversityConfig)
    scene: SceneConfig = field(default_factory=SceneConfig)
    stability: StabilityConfig = field(default_factory=StabilityConfig)
    curate: CurateConfig = field(default_factory=CurateConfig)
    energy: EnergyConfig = field(default_factory=EnergyConfig)
    lift: LiftConfig = field(default_factory=LiftConfig)
    evaluate: EvaluateConfig = field(default_factory=EvaluateConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    sample: SampleConfig = field(default_factory=SampleConfig)
    post_optimize: PostOptimizeConfig = field(default_factory=PostOptimizeConfig)
    optimize_grasps: OptimizeGraspsConfig = field(default_factory=OptimizeGraspsConfig)
    loop: LoopConfig = field(default_factory=LoopConfig)


def build_config(mapping: dict | None, where: str = "config") -> PipelineConfig:
    """The typed tree of a config mapping; absent sections and keys take their defaults, and a renamed or
    removed key fails naming its replacement (``config.retired_keys_message``)."""
    if retired := retired_keys_message(mapping or {}):
        raise ConfigError(f"{where}: {retired}")
    return from_section(PipelineConfig, mapping, where)


def stage_config(text: str, option: str = "--config-json") -> PipelineConfig:
    """A stage's ``--config-json`` (inline JSON or a file; the sections it reads) as the typed tree."""
    return build_config(parse_config_json(text, option), option)
