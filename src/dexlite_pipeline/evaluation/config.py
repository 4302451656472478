"""The evaluation's config type: section ``evaluate`` (with ``evaluate.writeup_protocol``), and the names it checks.

A leaf of the config tree (``settings``): it imports no evaluation code, so a stage's code hash
(``codehash``) covers this shape without the simulation or the metrics.
"""

from __future__ import annotations

from dataclasses import dataclass

from dexlite_pipeline.config import setting
from dexlite_pipeline.energy.config import EnergyThresholds

JOINT_ENTROPY_BINS = 100  # default bins per joint of the joint-angle entropy (evaluation.metrics)
PCA_COMPONENTS = (1, 2, 3, 5)  # default k of the cumulative PCA explained variance (evaluation.metrics)
METHODS = (
    "optimization", "cvae_raw", "cvae_post", "random_post", "dexgraspnet",
    "cvae_recon", "cvae_recon_post", "cvae_prior_train", "cvae_prior_train_post", "shipped_raw", "shipped_post",
    "cvae_ranked", "cvae_ranked_post",
)  # fmt: skip
RANKED_METHODS = ("cvae_ranked", "cvae_ranked_post")  # need the learned evaluator (evaluator.enabled)
# Frozen random-stream labels: a method's seeded draws (the evaluation's choice of grasps per
# object, selection.select_grasps; the report's pictured grasps, report.pictures.pick_examples)
# hash a label, and a method renamed after results were published keeps its old label there, so
# that a seed still draws the same grasps. Never change these values.
FROZEN_DRAW_LABELS = {"optimization": "seed"}  # "seed": the method's name before issue 23


def draw_label(method: str) -> str:
    """The label ``method``'s random draws are derived from: its frozen old name, or its name."""
    return FROZEN_DRAW_LABELS.get(method, method)

SPLITS = ("train", "heldout")  # the values of the object catalogs' ``split`` column
# The learning ladder: rung of each method. Fit and in-distribution rows are measured on the
# training objects whatever ``evaluate.splits`` says; held-out rows are the other methods'.
LADDER_RUNGS = {
    "cvae_recon": "fit", "cvae_recon_post": "fit",
    "cvae_prior_train": "in_distribution", "cvae_prior_train_post": "in_distribution",
}  # fmt: skip
LADDER_SPLIT = "train"


@dataclass(frozen=True)
class DiversityConfig:
    """Section ``diversity`` of config.yaml: when two grasps count as one."""

    distinct_translation_m: float = setting(0.02, "palms closer than this (m) ...", exclusive_minimum=0)
    distinct_rotation_deg: float = setting(
        30.0, "... and turned less than this (deg) from each other are one grasp", exclusive_minimum=0, maximum=180)
    coverage_patches: int = setting(
        256, "surface coverage: each object's surface in this many ~equal-area patches (farthest-point centres)", minimum=1)
    coverage_contact_m: float = setting(
        0.005, "a hand contact candidate within this of the surface (m) touches its patch (the lift test's 5 mm)", exclusive_minimum=0)

    def __post_init__(self):
        if self.distinct_translation_m <= 0 or self.distinct_rotation_deg <= 0:
            raise ValueError("config.diversity: distinct_translation_m and distinct_rotation_deg must be > 0")
        if self.coverage_patches < 1 or self.coverage_contact_m <= 0:
            raise ValueError("config.diversity: coverage_patches must be >= 1 and coverage_contact_m > 0")


@dataclass(frozen=True)
class WriteupProtocolConfig:
    """Config ``evaluate.writeup_protocol``: the own lift test of the DexLite write-up (Murali), a second, lenient measure beside ours.

    Its physics differs from ours in these constants (lift test only); everything else is ours.
    """

    enabled: bool = setting(True, "also lift-test every evaluated grasp under the write-up's test")
    friction: float = setting(2.0, "the write-up's MuJoCo test: friction 2 ...", minimum=0)
    preclose_rad: float = setting(0.07, "... fingers' flexion targets closed a further 0.07 rad ...", minimum=0)
    contact_condim: int = setting(6, "... torsional and rolling friction (condim 6) ...", enum=(1, 3, 4, 6))
    success_lift_ratio: float = setting(
        0.7, "... and success at a lift ratio above 0.7 (its 10 ms step and kp 100 are not copied)", exclusive_minimum=0, maximum=1)

    def lift_overrides(self) -> dict:
        return {"friction": self.friction, "preclose_rad": self.preclose_rad, "contact_condim": self.contact_condim,
                "success_lift_ratio": self.success_lift_ratio, "six_directions": False}


@dataclass(frozen=True)
class EvaluateConfig:
    """Config section ``evaluate``."""

    # rules: the evaluation steps that read the key (evaluation.step_keys): evaluate_simulate, evaluate (the aggregate
    # step) and report; a key changed reruns only those
    methods: tuple[str, ...] = setting(
        METHODS, "rows of metrics.csv (dexgraspnet only when dexgraspnet.root is set); cvae_recon* and cvae_prior_train* are "
        "the learning ladder's fit and in-distribution rungs (training objects); shipped_* the shipped model "
        "(sample.shipped_model) on held-out objects it never trained on; cvae_ranked* the model's samples ranked by the learned "
        "evaluator (left out when evaluator.enabled is false); missing inputs are reported, not invented",
        items={"enum": METHODS}, unique_items=True, rules=("evaluate_simulate", "evaluate"))
    splits: tuple[str, ...] = setting(
        ("heldout",), "object splits evaluated: train and/or heldout (catalog column split; a split with no objects is an error)",
        items={"enum": SPLITS}, min_items=1, unique_items=True, rules=("evaluate_simulate", "evaluate"))
    grasps_per_object: int = setting(
        16, "cap on simulated grasps per (method, object), seeded choice; cvae_raw, cvae_post and random_post share the choice "
        "(the same sampled rows); chosen grasps with invalid poses count as failures (n_invalid); metrics.csv's boot_ci95 "
        "columns resample objects", minimum=1, rules=("evaluate_simulate",))
    six_directions: bool = setting(
        True, "also run the six-direction disturbance test (DexGraspBench)", rules=("evaluate_simulate",))
    filter_thresholds: EnergyThresholds = setting(
        factory=EnergyThresholds, rules=("evaluate",),
        doc="equal filtering: every method (all attempts of optimization too) is counted per attempt and after these "
        "thresholds (filtered_* columns; as curate.thresholds), E_fc and E_dis with the contacts of one search for every "
        "grasp (evaluation.filter_energy), never a method's own contacts or flags")
    entropy_bins: int = setting(
        JOINT_ENTROPY_BINS, "bins over each joint's range for the joint-angle entropy (DexGraspNet)", minimum=2, rules=("evaluate",))
    pca_components: tuple[int, ...] = setting(
        PCA_COMPONENTS, "k of the cumulative PCA explained-variance columns", items={"minimum": 1}, min_items=1, rules=("evaluate",))
    energy_batch_size: int = setting(
        256, "grasps per energy evaluation batch", minimum=1, result_neutral=True, rules=("evaluate_simulate",))
    rendered_per_method: int = setting(2, "successes and failures pictured per method in report.html", minimum=0, rules=("report",))
    ladder_grasps_per_object: int = setting(
        8, "cap on simulated grasps per (ladder method, training object)", minimum=1, rules=("evaluate_simulate",))
    writeup_protocol: WriteupProtocolConfig = setting(
        factory=WriteupProtocolConfig, rules=("evaluate_simulate",),
        doc="every evaluated grasp is also lift-tested under the own, more lenient test of the DexLite write-up (Murali, "
        "README), reported in columns writeup_protocol_* beside ours (never in place of it); lift test only, ~0.1 s a grasp")

    def __post_init__(self) -> None:
        unknown = sorted(set(self.methods) - set(METHODS))
        if unknown:
            raise ValueError(f"config.evaluate.methods: unknown method(s) {', '.join(unknown)} (known: {', '.join(METHODS)})")
        unknown = sorted(set(self.splits) - set(SPLITS))
        if unknown:
            raise ValueError(f"config.evaluate.splits: unknown split(s) {', '.join(unknown)} (known: {', '.join(SPLITS)})")
        if self.grasps_per_object < 1 or self.ladder_grasps_per_object < 1 or self.entropy_bins < 2 or self.energy_batch_size < 1 or self.rendered_per_method < 0:
            raise ValueError(
                "config.evaluate: grasps_per_object, ladder_grasps_per_object, energy_batch_size >= 1, entropy_bins >= 2, rendered_per_method >= 0"
            )

    def splits_of(self, method: str) -> tuple[str, ...]:
        """The object splits a method is evaluated on: the training objects for the ladder's rungs, else ``splits``."""
        return (LADDER_SPLIT,) if method in LADDER_RUNGS else self.splits

    def cap_of(self, method: str) -> int:
        return self.ladder_grasps_per_object if method in LADDER_RUNGS else self.grasps_per_object
