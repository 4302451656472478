"""The evaluation's config type: section ``evaluate`` (with ``evaluate.writeup_protocol``), and the names it checks.

A leaf of the config tree (``settings``): it imports no evaluation code, so a stage's code hash
(``codehash``) covers this shape without the simulation or the metrics.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from dexlite_pipeline.energy.config import EnergyThresholds

JOINT_ENTROPY_BINS = 100  # default bins per joint of the joint-angle entropy (evaluation.metrics)
PCA_COMPONENTS = (1, 2, 3, 5)  # default k of the cumulative PCA explained variance (evaluation.metrics)
METHODS = (
    "optimization", "cvae_raw", "cvae_post", "random_post", "dexgraspnet",
    "cvae_recon", "cvae_recon_post", "cvae_prior_train", "cvae_prior_train_post", "shipped_raw", "shipped_post",
)  # fmt: skip
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

    distinct_translation_m: float = 0.02  # palms closer than this (m) ...
    distinct_rotation_deg: float = 30.0  # ... and turned less than this (deg) from each other are one grasp
    coverage_patches: int = 256  # surface patches per object for the coverage share (farthest-point centres)
    coverage_contact_m: float = 0.005  # a hand contact candidate this close to the surface (m) touches its patch

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

    enabled: bool = True
    friction: float = 2.0
    preclose_rad: float = 0.07
    contact_condim: int = 6
    success_lift_ratio: float = 0.7

    def lift_overrides(self) -> dict:
        return {"friction": self.friction, "preclose_rad": self.preclose_rad, "contact_condim": self.contact_condim,
                "success_lift_ratio": self.success_lift_ratio, "six_directions": False}


@dataclass(frozen=True)
class EvaluateConfig:
    """Config section ``evaluate``."""

    methods: tuple[str, ...] = METHODS  # methods to evaluate (missing inputs are reported, not invented)
    splits: tuple[str, ...] = ("heldout",)  # object splits to evaluate (catalog column ``split``)
    grasps_per_object: int = 16  # cap per (method, object) on simulated grasps
    six_directions: bool = True  # also run the six-direction disturbance test
    filter_thresholds: EnergyThresholds = field(default_factory=EnergyThresholds)  # the energy filter every method is also counted after
    entropy_bins: int = JOINT_ENTROPY_BINS  # bins per joint of the joint-angle entropy
    pca_components: tuple[int, ...] = PCA_COMPONENTS  # k of the cumulative PCA explained variance columns
    energy_batch_size: int = 256  # grasps per energy evaluation batch
    rendered_per_method: int = 2  # successes and failures pictured per method in the report
    ladder_grasps_per_object: int = 8  # cap per (ladder method, training object) on simulated grasps
    writeup_protocol: WriteupProtocolConfig = field(default_factory=WriteupProtocolConfig)  # the write-up's lenient test beside ours

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
