"""The typed configuration tree: one class per section of ``config.yaml``, one root that holds them.

``PipelineConfig`` mirrors the file section by section; each section's class lives with the
component it configures (``objects.config.ObjectsConfig``, ``sim.config.LiftConfig``, ...)
and shared shapes are one type wherever they appear: ``EnergyWeights`` (``energy.weights``,
``train.energy_weights``, ``post_optimize.energy_weights``), ``AnnealingSchedule``
(``optimize_grasps.annealing``, ``post_optimize.annealing``), ``EnergyThresholds``
(``optimize_grasps.thresholds``, ``curate.thresholds``) and ``InitConfig`` (``optimize_grasps.init``,
``post_optimize.random_init``). The dataclass fields are the one source of every key: default,
comment and schema constraints (``config.setting``); the schema and the documented default
``config.yaml`` are generated from them (``config_files``; ``tests/test_config.py`` fails when
either is stale).

The section classes live in leaf modules (each component's ``config`` module) that import no
pipeline code but ``dexlite_pipeline.config`` and each other: a stage imports this tree without importing other components' code, so its code hash
(``codehash``) covers only the code it runs (docs/design.md, "Code hashes").
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from dexlite_pipeline.config import ConfigError, from_section, parse_config_json, retired_keys_message, setting
from dexlite_pipeline.curation.config import CurateConfig
from dexlite_pipeline.energy.config import EnergyConfig
from dexlite_pipeline.evaluation.config import DiversityConfig, EvaluateConfig
from dexlite_pipeline.evaluator.config import EvaluatorSection
from dexlite_pipeline.io.config import DexGraspNetConfig, GraspDatasetConfig, ModelBatchConfig
from dexlite_pipeline.loop.config import LoopConfig
from dexlite_pipeline.model.config import SampleConfig, TrainConfig
from dexlite_pipeline.objects.config import ObjectsConfig, StabilityConfig
from dexlite_pipeline.optim.config import OptimizeGraspsConfig, PostOptimizeConfig
from dexlite_pipeline.sim.config import LiftConfig, SceneConfig


SHADOW = "shadow"  # config key ``hand``'s default: the built-in Shadow Hand (``hand.model.ShadowHand``)
# The shipped hands are the folders of data/hands/ (``hand.description.SHIPPED_HANDS``); read from the folder here so that
# the config (and the workflow while it parses) checks a hand's name without importing the hand code (torch, MuJoCo).
SHIPPED_HANDS_DIR = Path(__file__).resolve().parent / "data" / "hands"


def hand_names() -> tuple[str, ...]:
    """The hand names config key ``hand`` knows: shadow and the shipped hands (``data/hands/<name>/right_hand.xml``)."""
    shipped = sorted(p.parent.name for p in SHIPPED_HANDS_DIR.glob("*/right_hand.xml"))
    return (SHADOW, *shipped)


def hand_setting_problem(value: str) -> str:
    """One line saying why config key ``hand`` cannot be ``value`` ("" when it can): not a known hand name, and no
    file at that path (relative to the working directory). An existing file's MJCF is read, and refused with its
    reason, when the hand is made (``hand.choice.resolve_hand``), not here: that needs MuJoCo."""
    text = str(value)
    if text in hand_names():
        return ""
    path = Path(text).expanduser()
    if path.is_file():
        return ""
    kind = "no such file" if path.suffix.lower() == ".xml" or "/" in text else "not a hand name and no such file"
    return f"hand: {text}: {kind} (a hand is {', '.join(hand_names())} or the path of an MJCF file)"


@dataclass(frozen=True)
class PipelineConfig:
    """The whole of ``config.yaml``."""

    seed: int = setting(0, "global random seed; every stage derives its own from it", minimum=0, required=True)
    device: str = setting(
        "auto", "auto (CUDA when present, else CPU), cpu, cuda, cuda:N", pattern="^(auto|cpu|cuda(:[0-9]+)?)$", required=True)
    shards: int = setting(2, "grasp-heavy stages split objects into this many groups", minimum=1, required=True)
    hand: str = setting(
        SHADOW, "the hand: shadow, allegro, leap (shipped) or the path of a hand's MJCF file (docs/hands.md); every stage takes it "
        "(a grasp dataset holds one hand's grasps; a model and an evaluator are of one hand)",
        pattern="^.+$")
    objects: ObjectsConfig = setting(factory=ObjectsConfig, required=True)
    dexgraspnet: DexGraspNetConfig = setting(factory=DexGraspNetConfig, required=True)
    dataset: GraspDatasetConfig = setting(
        factory=GraspDatasetConfig, doc='training grasps from a grasp dataset instead of optimizing them (docs/design.md, "The grasp '
        'dataset and its campaign")')
    model_batch: ModelBatchConfig = setting(
        factory=ModelBatchConfig, doc='a dataset batch made by the model, the optimization from scratch topping up (workflow/rules/'
        'model_batch.smk; docs/design.md, "Model-made batches")')
    diversity: DiversityConfig = setting(factory=DiversityConfig, doc="when two grasps of one object count as one (evaluate, dexlite grasp)")
    scene: SceneConfig = setting(
        factory=SceneConfig, doc='where the object is (stages from optimize_grasps on; docs/design.md, "Tabletop mode")')
    stability: StabilityConfig = setting(
        factory=StabilityConfig, doc="PyBullet table test (stability_filter): later stages use stable objects only")
    curate: CurateConfig = setting(factory=CurateConfig)
    energy: EnergyConfig = setting(
        factory=EnergyConfig, doc="optimization from scratch, curation, evaluation (training and post-optimization: weights of their own)")
    lift: LiftConfig = setting(factory=LiftConfig, doc="MuJoCo lift test (lift_validate, evaluate, `dexlite lift-test`); echoed in outputs")
    evaluate: EvaluateConfig = setting(factory=EvaluateConfig)
    train: TrainConfig = setting(
        factory=TrainConfig, doc="PointNet + CVAE training (the default fits its data in minutes on 2 CPU cores; the write-up's "
        "values: config/profiles/writeup_gpu.yaml, --configfile it on a GPU machine)")
    evaluator: EvaluatorSection = setting(
        factory=EvaluatorSection, doc="a learned grasp evaluator trained on the run's simulated grasps ranks the model's samples "
        '(rows cvae_ranked*; docs/design.md, "The learned evaluator")')
    sample: SampleConfig = setting(factory=SampleConfig)
    post_optimize: PostOptimizeConfig = setting(factory=PostOptimizeConfig)
    optimize_grasps: OptimizeGraspsConfig = setting(
        factory=OptimizeGraspsConfig, doc="grasp optimization from scratch (DexGraspNet's optimizer, retuned shorter schedule)")
    loop: LoopConfig = setting(
        factory=LoopConfig, doc="the data loop (Dex1B): each round samples with the last model, keeps the new distinct grasps that "
        'hold and retrains (docs/design.md, "The data loop"); results/round_<r>/, results/loop.csv')

def build_config(mapping: dict | None, where: str = "config") -> PipelineConfig:
    """The typed tree of a config mapping; absent sections and keys take their defaults, and a renamed or
    removed key fails naming its replacement (``config.retired_keys_message``), an unusable ``hand`` naming it
    (``hand_setting_problem``)."""
    if retired := retired_keys_message(mapping or {}):
        raise ConfigError(f"{where}: {retired}")
    built = from_section(PipelineConfig, mapping, where)
    if problem := hand_setting_problem(built.hand):
        raise ConfigError(f"{where}: {problem}")
    return built


def stage_config(text: str, option: str = "--config-json") -> PipelineConfig:
    """A stage's ``--config-json`` (inline JSON or a file; the sections it reads) as the typed tree."""
    return build_config(parse_config_json(text, option), option)
