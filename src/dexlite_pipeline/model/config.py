"""The model's config types: the network (``train.model``), sections ``train`` and ``sample``.

A leaf of the config tree (``settings``): it imports no model code, so a stage's code hash
(``codehash``) covers these shapes without the network, training or sampling code.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from dexlite_pipeline.config import json_ready
from dexlite_pipeline.energy.config import EnergyWeights
from dexlite_pipeline.model.shipped import SHIPPED_MODEL_RELATIVE

NORMALIZATIONS = ("batch", "none")
POSE_FRAMES = ("object", "point", "surface", "hand")


@dataclass(frozen=True)
class ModelConfig:
    """Network sizes (the reference values are the write-up's), the pose frame and PointNet's inputs."""

    pointnet_widths: tuple[int, ...] = (64, 128, 1024, 256)
    encoder_hidden: tuple[int, ...] = (256, 512, 256)
    decoder_hidden: tuple[int, ...] = (256, 512, 256)
    latent_dim: int = 256
    normalization: str = "batch"
    pose_frame: str = "surface"
    point_normals: bool = True

    def __post_init__(self) -> None:
        if self.normalization not in NORMALIZATIONS:
            raise ValueError(f"model normalization {self.normalization!r} is not one of {', '.join(NORMALIZATIONS)}")
        if self.pose_frame not in POSE_FRAMES:
            raise ValueError(f"model pose_frame {self.pose_frame!r} is not one of {', '.join(POSE_FRAMES)}")
        if not self.pointnet_widths or min(self.pointnet_widths) < 1 or self.latent_dim < 1:
            raise ValueError("model sizes must be positive")

    @property
    def condition_dim(self) -> int:
        return 2 * self.pointnet_widths[-1]

    @property
    def frame_input_dim(self) -> int:
        """Extra network inputs that describe the pose frame: the vertical in the ``hand`` frame."""
        return 3 if self.pose_frame == "hand" else 0

    def to_dict(self) -> dict:
        return json_ready(self)

    @staticmethod
    def from_dict(values: dict) -> "ModelConfig":
        return ModelConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})


ENERGY_TERMS = ("fc", "dis", "pen", "spen", "joints")
LOSS_TERMS = ("recon", "kl", *ENERGY_TERMS)
TABLE_TERM = "table"  # E_table, a loss term in tabletop mode only (after LOSS_TERMS)
LR_SCHEDULES = ("constant", "cosine")


@dataclass(frozen=True)
class TrainConfig:
    """Config section ``train`` (two documented profiles: the default and ``config/profiles/writeup_gpu.yaml``)."""

    profile: str = "default"
    epochs: int = 100000
    max_steps: int = 8000
    batch_size: int = 64
    clouds_per_batch: int = 4
    points_per_cloud: int = 256
    learning_rate: float = 2e-3
    validation_fraction: float = 0.1
    min_grasps: int = 8
    max_training_objects: int = 0  # train on a seeded subset of this many training objects (0 = all): the learning curve
    energy_point_spacing_m: float = 0.006  # mean spacing of E_pen's object points in the loss, m (coarser: training cost)
    contact_samples: int = 32
    rotation_augmentation: bool = False
    fixed_clouds: bool = True
    lr_schedule: str = "cosine"
    lr_warmup_steps: int = 200
    grad_clip_norm: float = 1.0
    energy_warmup_fraction: float = 0.3
    weight_recon: float = 1.0
    weight_kl: float = 1e-5
    energy_weights: EnergyWeights = field(default_factory=lambda: EnergyWeights(fc=0.0, dis=0.0, pen=0.0, spen=0.0, joints=0.0, table=0.0))
    model: ModelConfig = field(default_factory=lambda: ModelConfig(normalization="none"))

    def __post_init__(self) -> None:
        if self.batch_size < 1 or self.clouds_per_batch < 1 or self.points_per_cloud < 1 or self.epochs < 1:
            raise ValueError("train: batch_size, clouds_per_batch, points_per_cloud and epochs must be positive")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ValueError(f"train.lr_schedule {self.lr_schedule!r} is not one of {', '.join(LR_SCHEDULES)}")
        if self.model.normalization == "batch" and self.clouds_per_batch < 2:
            raise ValueError("train: BatchNorm needs clouds_per_batch >= 2 (one cloud per batch erases object size); use model.normalization: none")

    def weights(self, table: bool = False) -> dict[str, float]:
        """Loss term -> weight: recon and kl, then the energy terms (fc, dis, pen, spen, joints; with ``table``, E_table last)."""
        weights = {"recon": self.weight_recon, "kl": self.weight_kl, **dataclasses.asdict(self.energy_weights)}
        return {term: weights[term] for term in (LOSS_TERMS if not table else (*LOSS_TERMS, TABLE_TERM))}


LATENT_PRIORS = ("standard", "aggregate", "neighbours")
ANCHOR_RULES = ("uniform", "matched", "debiased", "spread")


@dataclass(frozen=True)
class SampleConfig:
    """Config section ``sample``."""

    synthesis_grasps_per_object: int = 32  # held-out objects: pure synthesis
    expansion_grasps_per_object: int = 16  # training objects with lift-validated grasps
    scales: tuple[float, ...] = (0.08, 0.10, 0.12)  # synthesis scales, dealt in turn (those of the training grasps)
    expansion_latent_std: float = 0.5  # sigma of the latent perturbation
    expansion_point_fraction: float = 0.5  # share of expansions that move the associated point instead
    expansion_point_neighbours: int = 16  # the moved point is one of this many nearest cloud points
    points_per_cloud: int = 0  # 0 = the value the model was trained with
    ladder: bool = True  # also sample the learning ladder's rows on training objects (reconstructions, prior samples)
    ladder_grasps_per_object: int = 0  # ladder rows per training object and rung (0: every training grasp, synthesis_grasps_per_object prior samples)
    shipped_model: str = str(SHIPPED_MODEL_RELATIVE)  # pretrained model (path in the checkout) also sampled on held-out objects (rows shipped_raw); "" = none
    latent_prior: str = "neighbours"  # where synthesis draws latents: standard N(0, I), the training codes' aggregate or its nearest clouds' codes
    latent_temperature: float = 1.0  # scale of the latent noise (of N(0, I), or of each training code's posterior sigma)
    anchor_rule: str = "matched"  # associated points of pure synthesis: uniform, matched to each latent's training grasp, debiased or spread
    neighbour_clouds: int = 8  # latent prior ``neighbours``: codes of this many nearest training clouds
    anchor_region_m: float = 0.02  # anchor rule ``debiased``: a drawn associated point counts against cloud points this close (m)
    debias_training: bool = False  # anchor rule ``debiased``: counts start from the training grasps matching each point
    match_candidates: int = 1  # anchor rule ``matched``: debiased draw among this many best-matching points (1: the best)
    debias_codes: bool = True  # training-code priors: a cloud's draws prefer codes it has drawn less (weight / (count + 1))

    def __post_init__(self) -> None:
        if not self.scales or min(self.scales) <= 0:
            raise ValueError("sample.scales must be a non-empty list of positive scales")
        if self.neighbour_clouds < 1:
            raise ValueError(f"sample.neighbour_clouds must be >= 1, got {self.neighbour_clouds}")
        if self.match_candidates < 1:
            raise ValueError(f"sample.match_candidates must be >= 1, got {self.match_candidates}")
        if self.anchor_region_m <= 0:
            raise ValueError(f"sample.anchor_region_m must be > 0, got {self.anchor_region_m}")
        if self.anchor_rule not in ANCHOR_RULES:
            raise ValueError(f"sample.anchor_rule {self.anchor_rule!r} is not one of {', '.join(ANCHOR_RULES)}")
        if self.latent_prior not in LATENT_PRIORS:
            raise ValueError(f"sample.latent_prior {self.latent_prior!r} is not one of {', '.join(LATENT_PRIORS)}")
