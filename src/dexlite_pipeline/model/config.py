"""The model's config types: the network (``train.model``), sections ``train`` and ``sample``.

A leaf of the config tree (``settings``): it imports no model code, so a stage's code hash
(``codehash``) covers these shapes without the network, training or sampling code.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from dexlite_pipeline.config import json_ready, setting
from dexlite_pipeline.energy.config import EnergyWeights
from dexlite_pipeline.model.shipped import SHIPPED_MODEL_RELATIVE

NORMALIZATIONS = ("batch", "none")
POSE_FRAMES = ("object", "point", "surface", "hand")


@dataclass(frozen=True)
class ModelConfig:
    """Network sizes (the reference values are the write-up's), the pose frame and PointNet's inputs."""

    pointnet_widths: tuple[int, ...] = setting(
        (64, 128, 1024, 256), "1-D conv widths; the last is the per-point/global feature size", items={"minimum": 1}, min_items=1)
    encoder_hidden: tuple[int, ...] = setting((256, 512, 256), "encoder MLP hidden widths", items={"minimum": 1})
    decoder_hidden: tuple[int, ...] = setting((256, 512, 256), "decoder MLP hidden widths", items={"minimum": 1})
    latent_dim: int = setting(256, "latent size", minimum=1)
    normalization: str = setting(
        "batch", "PointNet norm: none (one cloud per batch) or batch (needs clouds_per_batch >= 2)", enum=NORMALIZATIONS)
    pose_frame: str = setting(
        "surface", "frame of the palm pose the networks see: object, point (translation from the associated point), surface "
        "(position and rotation in a frame at that point, x along its normal) or hand (surface, turned about the normal to the "
        "palm's roll, which becomes an input)", enum=POSE_FRAMES)
    point_normals: bool = setting(True, "PointNet reads each point's outward normal beside its position (6 input channels)")
    refiner_hidden: tuple[int, ...] = setting(
        (), "hidden widths of the refiner, an MLP after the decoder that reads where the decoded hand's pad points and "
        "keypoints lie against the cloud (height over the nearest point's tangent plane, distance) and corrects the pose "
        "in one pass (model/refiner.py; needs point_normals); empty: no refiner", items={"minimum": 1})
    refiner_passes: int = setting(
        1, "how many times the refiner reads the surface and corrects the pose (the same weights each pass; training "
        "unrolls the passes)", minimum=1)

    def __post_init__(self) -> None:
        if self.normalization not in NORMALIZATIONS:
            raise ValueError(f"model normalization {self.normalization!r} is not one of {', '.join(NORMALIZATIONS)}")
        if self.pose_frame not in POSE_FRAMES:
            raise ValueError(f"model pose_frame {self.pose_frame!r} is not one of {', '.join(POSE_FRAMES)}")
        if not self.pointnet_widths or min(self.pointnet_widths) < 1 or self.latent_dim < 1:
            raise ValueError("model sizes must be positive")
        if self.refiner_hidden and not self.point_normals:
            raise ValueError("model refiner_hidden: the refiner reads the cloud's normals; set model point_normals: true")

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
# model.surface_terms' loss terms (after the others, each when its weight is above 0): the penetration and the pads'
# heights over the surface, read off the objects' surface samples
SURFACE_PENETRATION_TERM, SURFACE_DISTANCE_TERM = "surface_pen", "surface_dis"
SURFACE_TERMS = (SURFACE_PENETRATION_TERM, SURFACE_DISTANCE_TERM)
REFINE_TERM = "refine"  # the refined pose's squared error (models with a refiner, ``model.refiner_hidden``), weighed as recon
LR_SCHEDULES = ("constant", "cosine")
GENERATORS = ("cvae", "flow")  # the generative families behind PointNet (``network.GraspCVAE``, ``flow.GraspFlow``)
FLOW_SOLVERS = ("euler", "heun")


@dataclass(frozen=True)
class TrainConfig:
    """Config section ``train`` (two documented profiles: the default and ``config/profiles/writeup_gpu.yaml``)."""

    profile: str = setting("default", "label recorded in cvae.pt")
    generator: str = setting(
        "cvae", "generative family: cvae (conditional VAE, latents drawn from the training codes) or flow (conditional flow "
        "matching: a velocity network integrated from Gaussian noise to a pose, same conditioning, anchors and pose frame); "
        "recorded in the model file", enum=GENERATORS)
    flow_steps: int = setting(
        8, "generator flow: ODE steps from noise to pose at sampling (and back, to encode a known grasp)", minimum=1)
    flow_solver: str = setting(
        "heun", "generator flow: the ODE's step rule, euler (one velocity per step) or heun (two, second order)", enum=FLOW_SOLVERS)
    seed: int = setting(
        -1, "seed of the training alone (initial weights, batches, validation split, the max_training_objects and "
        "max_grasps_per_object subsets; the CVAE's and the learned evaluator's): training seeds on the same data; -1 = the run's "
        "seed", minimum=-1)
    epochs: int = setting(100000, "passes over the training grasps (the step budget, max_steps, ends training first)", minimum=1)
    max_steps: int = setting(8000, "optimizer-step budget (0 = epochs only)", minimum=0)
    batch_size: int = setting(64, "grasps per step", minimum=1)
    clouds_per_batch: int = setting(
        4, "distinct (object, scale) clouds per step: PointNet runs once per cloud; one cloud holds only a few grasps, so "
        "several make a batch of useful size", minimum=1)
    points_per_cloud: int = setting(256, "object surface points fed to PointNet (the write-up: 2048)", minimum=1)
    learning_rate: float = setting(2e-3, "Adam peak learning rate (the write-up: 1e-4 over 100 epochs)", exclusive_minimum=0)
    validation_fraction: float = setting(
        0.1, "share of the grasps held out for the validation curve (seeded)", minimum=0, maximum=0.9)
    min_grasps: int = setting(8, "fewer lift-successful training grasps is an error", minimum=1)
    max_training_objects: int = setting(
        0, "train on a seeded subset of this many training objects with grasps (0 = all): the learning curve", minimum=0)
    max_training_families: int = setting(
        0, "train on the objects of a seeded subset of this many families (objects.family.object_family: a household "
        "family, procedural, other; 0 = all), before max_training_objects: the learning curve against families", minimum=0)
    max_grasps_per_object: int = setting(
        0, "train on a seeded choice of at most this many lift-successful grasps per object (0 = all): the learning curve "
        "against grasps per object", minimum=0)
    energy_point_spacing_m: float = setting(
        0.006, "mean spacing of E_pen's object points in the loss, m (coarser than the checks: training cost)", exclusive_minimum=0)
    contact_samples: int = setting(
        32, "loss contacts of grasps without stored contacts (imported): best of this many near-surface pad 4-sets per decoded "
        "pose (0 = nearest four pads); optimized grasps use the contacts they were made with", minimum=0)
    rotation_augmentation: bool = setting(
        False, "turn each cloud and its grasps about the object's z axis (up on the table) by a random angle every step; off: "
        "sampling matches each new object's heading instead (sample.yaw_candidates), which held 5 points more on the "
        "household split at random yaw (docs/learning.md, \"Any yaw\")")
    fixed_clouds: bool = setting(
        True, "each object's cloud is one fixed farthest-point subset (false: a new random subset every step, which moves each "
        "grasp's associated point by ~1 cm)")
    lr_schedule: str = setting("cosine", "constant, or cosine decay to 0 over the planned steps after the warm-up", enum=LR_SCHEDULES)
    lr_warmup_steps: int = setting(200, "linear learning-rate warm-up, steps", minimum=0)
    grad_clip_norm: float = setting(1.0, "clip the gradient's global norm to this (0 = off)", minimum=0)
    energy_warmup_fraction: float = setting(0.3, "energy weights ramp 0 -> full over this share of the steps", minimum=0, maximum=1)
    weight_recon: float = setting(
        1.0, "reconstruction squared error, summed over translation (0.1 m), rotation matrix, joints (rad)", minimum=0)
    weight_kl: float = setting(
        1e-5, "KL divergence to N(0, I); small, so each grasp keeps a distinct code (sampling draws from the codes' aggregate, "
        "sample.latent_prior, not from N(0, I))", minimum=0)
    weight_surface_penetration: float = setting(
        0.0, "penetration of the decoded hand read off the object's surface samples, metres (model.surface_terms: no SDF "
        "grid or mesh, so it fits a dataset of any size; 0 = not computed); ramps in with the energies "
        "(energy_warmup_fraction)", minimum=0)
    refiner_start_noise_m: float = setting(
        0.0, "models with a refiner (model.refiner_hidden): standard deviation (m, per axis) of a random shift of the "
        "decoded palm before the refiner reads it in training, so it learns to correct misses larger than the decoder's "
        "on its training grasps", minimum=0)
    weight_surface_distance: float = setting(
        0.0, "the training grasp's finger-pad heights over the object's surface, decoded against trained: mean squared "
        "difference, cm², over the pads within 1 cm of the surface (model.surface_terms; 0 = not computed); ramps in with "
        "the energies", minimum=0)
    energy_weights: EnergyWeights = setting(
        factory=lambda: EnergyWeights(fc=0.0, dis=0.0, pen=0.0, spen=0.0, joints=0.0, table=0.0),
        doc="energy terms of the decoded pose in the loss (all 0: not computed; the write-up's are 1/100/100/10/1)")
    model: ModelConfig = setting(
        factory=lambda: ModelConfig(normalization="none"), doc="the networks (sizes: the write-up's), the pose frame and PointNet's inputs")

    def __post_init__(self) -> None:
        if self.batch_size < 1 or self.clouds_per_batch < 1 or self.points_per_cloud < 1 or self.epochs < 1:
            raise ValueError("train: batch_size, clouds_per_batch, points_per_cloud and epochs must be positive")
        if self.generator not in GENERATORS:
            raise ValueError(f"train.generator {self.generator!r} is not one of {', '.join(GENERATORS)}")
        if self.flow_solver not in FLOW_SOLVERS or self.flow_steps < 1:
            raise ValueError(f"train.flow_solver must be one of {', '.join(FLOW_SOLVERS)} and flow_steps >= 1")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ValueError(f"train.lr_schedule {self.lr_schedule!r} is not one of {', '.join(LR_SCHEDULES)}")
        if self.model.normalization == "batch" and self.clouds_per_batch < 2:
            raise ValueError("train: BatchNorm needs clouds_per_batch >= 2 (one cloud per batch erases object size); use model.normalization: none")

    def training_seed(self, run_seed: int) -> int:
        """The seed the training uses: ``seed``, or the run's seed ``run_seed`` when it is -1."""
        return run_seed if self.seed < 0 else self.seed

    def weights(self, table: bool = False) -> dict[str, float]:
        """Loss term -> weight: recon and kl, then the energy terms (fc, dis, pen, spen, joints; with ``table``, E_table),
        then each of ``SURFACE_TERMS`` whose weight is above 0."""
        weights = {"recon": self.weight_recon, "kl": self.weight_kl, **dataclasses.asdict(self.energy_weights)}
        terms = {term: weights[term] for term in (LOSS_TERMS if not table else (*LOSS_TERMS, TABLE_TERM))}
        surface = {SURFACE_PENETRATION_TERM: self.weight_surface_penetration, SURFACE_DISTANCE_TERM: self.weight_surface_distance}
        return {**terms, **{term: weight for term, weight in surface.items() if weight > 0}}

    def surface_terms(self) -> tuple[str, ...]:
        """The surface-sample terms the loss weights (``SURFACE_TERMS`` above 0)."""
        return tuple(term for term in self.weights() if term in SURFACE_TERMS)

    def uses_mesh_energies(self, table: bool = False) -> bool:
        """Whether a weighted energy term needs the objects' SDF grids and meshes (``train.energy_weights``; E_table only on
        a table): the surface-sample terms do not."""
        return any(weight > 0 for name, weight in self.weights(table).items() if name in (*ENERGY_TERMS, TABLE_TERM))


LATENT_PRIORS = ("standard", "aggregate", "neighbours")
ANCHOR_RULES = ("uniform", "matched", "debiased", "spread")
# The grasp types a model may be asked for: optim.grasp_types.TYPE_NAMES (a config leaf cannot import it; a test checks
# that the two agree), and ANY_GRASP_TYPE, the training mix.
GRASP_TYPE_NAMES = ("power", "pinch", "tripod", "lateral", "rim")
ANY_GRASP_TYPE = "any"
# sample.type_mix: how "any" deals an object's samples to the model's types
TRAINING_TYPE_MIX, EVEN_TYPE_MIX = "training", "even"
TYPE_MIXES = (TRAINING_TYPE_MIX, EVEN_TYPE_MIX)


@dataclass(frozen=True)
class SampleConfig:
    """Config section ``sample``."""

    synthesis_grasps_per_object: int = setting(32, "pure synthesis (cvae_raw) per held-out object", minimum=0)
    expansion_grasps_per_object: int = setting(16, "dataset expansion per training object with lift-validated grasps", minimum=0)
    scales: tuple[float, ...] = setting(
        (0.08, 0.10, 0.12), "object scales (≈ radius, m) dealt in turn to synthesized grasps: those of the training grasps "
        "(optimize_grasps.scales); the model is not asked to extrapolate in size", items={"exclusive_minimum": 0}, min_items=1)
    real_size: bool = setting(
        False, "objects whose files are known to be in metres (generated household objects) are sampled at their real size "
        "instead of at the scales (a model trained on optimize_grasps.real_size grasps)")
    expansion_latent_std: float = setting(0.5, "σ of the latent perturbation z = μ + σ·ε", minimum=0)
    expansion_point_fraction: float = setting(
        0.5, "share of expansions that move the associated point instead of z", minimum=0, maximum=1)
    expansion_point_neighbours: int = setting(
        16, "the moved associated point is one of its this-many nearest cloud points", minimum=1)
    points_per_cloud: int = setting(0, "PointNet points per cloud (0 = as trained)", minimum=0)
    ladder: bool = setting(
        True, "also sample the learning ladder's rows on training objects (reconstructions of the training grasps, pure "
        "synthesis on training objects)")
    ladder_grasps_per_object: int = setting(
        0, "ladder rows per training object and rung: a seeded choice of its training grasps to reconstruct and as many prior "
        "samples (0 = every training grasp and synthesis_grasps_per_object prior samples); large runs cap it near evaluate's "
        "cap", minimum=0)
    shipped_model: str = setting(
        str(SHIPPED_MODEL_RELATIVE), "the pretrained model (path in this checkout) also sampled on the held-out objects it never "
        'trained on (methods shipped_raw, shipped_post); "" = none')
    latent_prior: str = setting(
        "neighbours", "latents of new grasps: standard N(0, I); aggregate (any training grasp's code with its posterior noise); "
        "neighbours (codes of the training clouds whose global PointNet feature is nearest the new object's: a conditional "
        "prior read off the data)", enum=LATENT_PRIORS)
    latent_temperature: float = setting(
        1.0, "scale of the latent noise (of N(0, I), or of each training code's posterior σ)", minimum=0)
    anchor_rule: str = setting(
        "matched", "associated point of a synthesized grasp: uniform over the cloud; matched (the point whose local feature is "
        "nearest that of the training grasp its latent came from); debiased (weight 1/(count+1), count = earlier draws "
        "nearby, Dex1B); spread (farthest point)", enum=ANCHOR_RULES)
    neighbour_clouds: int = setting(
        8, "latent_prior neighbours: how many nearest training clouds (object and scale) lend their codes", minimum=1)
    anchor_region_m: float = setting(
        0.02, "anchor_rule debiased: a drawn associated point counts against the cloud points within this (m)", exclusive_minimum=0)
    debias_training: bool = setting(
        False, "anchor_rule debiased: counts start from how many training grasps' local features match each point")
    match_candidates: int = setting(
        1, "anchor_rule matched: draw among this many best-matching points, debiased (1 = the best match)", minimum=1)
    yaw_candidates: int = setting(
        36, "headings tried per new object: it is sampled turned about z to the one of this many evenly spaced turns whose "
        "PointNet feature is nearest a training object's (each turned cloud moved to centre its bounding box, as a prepared "
        "object is), and the grasps turned back (the codes carry their training objects' headings); 1 = as it stands", minimum=1)
    debias_codes: bool = setting(
        True, "latent_prior aggregate / neighbours: a cloud's draws prefer training codes it drew less (1/(count+1))")
    grasp_type: str = setting(
        ANY_GRASP_TYPE, "grasp type of sampled grasps: any (each object's grasps dealt to the model's types in its training "
        "mix's proportions) or one type, which the model must know (a model trained without types knows power only)",
        enum=(ANY_GRASP_TYPE, *GRASP_TYPE_NAMES))
    type_mix: str = setting(
        TRAINING_TYPE_MIX, "with grasp_type any, how each object's samples are dealt to the model's types: training (in the "
        "proportions of its training grasps) or even (each type equally often, so a type that is rare in the training data is "
        "proposed on every object and the learned evaluator, ranking a pool, keeps the types that fit it)",
        enum=TYPE_MIXES)

    def __post_init__(self) -> None:
        if not self.scales or min(self.scales) <= 0:
            raise ValueError("sample.scales must be a non-empty list of positive scales")
        if self.neighbour_clouds < 1:
            raise ValueError(f"sample.neighbour_clouds must be >= 1, got {self.neighbour_clouds}")
        if self.match_candidates < 1:
            raise ValueError(f"sample.match_candidates must be >= 1, got {self.match_candidates}")
        if self.yaw_candidates < 1:
            raise ValueError(f"sample.yaw_candidates must be >= 1, got {self.yaw_candidates}")
        if self.anchor_region_m <= 0:
            raise ValueError(f"sample.anchor_region_m must be > 0, got {self.anchor_region_m}")
        if self.anchor_rule not in ANCHOR_RULES:
            raise ValueError(f"sample.anchor_rule {self.anchor_rule!r} is not one of {', '.join(ANCHOR_RULES)}")
        if self.latent_prior not in LATENT_PRIORS:
            raise ValueError(f"sample.latent_prior {self.latent_prior!r} is not one of {', '.join(LATENT_PRIORS)}")
        if self.type_mix not in TYPE_MIXES:
            raise ValueError(f"sample.type_mix {self.type_mix!r} is not one of {', '.join(TYPE_MIXES)}")
        if self.grasp_type not in (ANY_GRASP_TYPE, *GRASP_TYPE_NAMES):
            raise ValueError(f"sample.grasp_type {self.grasp_type!r} is not one of {', '.join((ANY_GRASP_TYPE, *GRASP_TYPE_NAMES))}")
