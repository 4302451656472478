"""The optimizer's config types: the annealing schedule, the start poses, sections ``optimize_grasps`` and ``post_optimize``.

A leaf of the config tree (``settings``): it imports no optimizer code, so a stage's code hash
(``codehash``) covers these shapes without the computation. ``AnnealingSchedule`` is the one
schedule type (``optimize_grasps.annealing``, ``post_optimize.annealing``) and ``InitConfig`` the one
start type (``optimize_grasps.init``, ``post_optimize.random_init``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from dexlite_pipeline.config import ConfigError, setting
from dexlite_pipeline.energy.config import EnergyThresholds, EnergyWeights


@dataclass(frozen=True)
class AnnealingSchedule:
    """The annealing schedule: step size, temperature and their decay (config ``optimize_grasps.annealing``,
    ``post_optimize.annealing``). Defaults: DexGraspNet's constants (6000 steps from scratch)."""

    iterations: int = setting(6000, "annealed optimizer steps", minimum=0)
    step_size: float = setting(0.005, "scaled-gradient step at iteration 0", exclusive_minimum=0)
    step_size_decay: float = setting(0.95, "step size × this every step_size_period iterations", exclusive_minimum=0, maximum=1)
    step_size_period: int = setting(50, "iterations between step-size decays", minimum=1)
    rmsprop_mu: float = setting(0.98, "weight of the new squared gradient in its running average (DexGraspNet)", minimum=0, maximum=1)
    rmsprop_eps: float = setting(1e-8, "added to the root of the squared-gradient average that scales the step", exclusive_minimum=0)
    rmsprop_statistic: str = setting(
        "grasp", "grasp: each grasp's own squared-gradient average (its steps do not depend on its batch; more grasps pass "
        "the energy thresholds: docs/results.md); batch: the average over the batch (DexGraspNet)", enum=("batch", "grasp"))
    contact_switch_probability: float = setting(
        0.5, "each contact re-drawn with this probability per step", minimum=0, maximum=1)
    starting_temperature: float = setting(18.0, "Metropolis T0 (energy units)", exclusive_minimum=0)
    temperature_decay: float = setting(0.95, "T × this every temperature_period iterations", exclusive_minimum=0, maximum=1)
    temperature_period: int = setting(30, "iterations between temperature decays", minimum=1)


@dataclass(frozen=True)
class HopelessStopConfig:
    """When a grasp stops optimizing early because it will not reach the energy thresholds (config
    ``optimize_grasps.stop_hopeless``, ``post_optimize.stop_hopeless``): after each of ``iterations``, a grasp whose
    kept state has E_fc above the matching ``max_e_fc`` or E_dis above the matching ``max_e_dis_m`` ends there. The
    lists go together, one entry per checkpoint; empty lists: every grasp runs every iteration."""

    iterations: tuple[int, ...] = setting((), "checkpoints, in optimizer iterations", items={"minimum": 1}, unique_items=True)
    max_e_fc: tuple[float, ...] = setting((), "stop a grasp whose force-closure residual E_fc is above this at the checkpoint",
                                          items={"exclusive_minimum": 0})
    max_e_dis_m: tuple[float, ...] = setting((), "... or whose contact distance E_dis is above this, metres", items={"exclusive_minimum": 0})

    def __post_init__(self) -> None:
        if not len(self.iterations) == len(self.max_e_fc) == len(self.max_e_dis_m):
            raise ValueError(f"stop_hopeless: iterations, max_e_fc and max_e_dis_m need one entry per checkpoint each, got "
                             f"{len(self.iterations)}, {len(self.max_e_fc)} and {len(self.max_e_dis_m)}")

    def limits_at(self, iteration: int) -> tuple[float, float] | None:
        """(max E_fc, max E_dis in m) if ``iteration`` is a checkpoint, else None."""
        if iteration not in self.iterations:
            return None
        k = self.iterations.index(iteration)
        return self.max_e_fc[k], self.max_e_dis_m[k]


@dataclass(frozen=True)
class AnnealingConfig(AnnealingSchedule):
    """Everything one optimizer run needs: the schedule plus what the run records and how it ends."""

    trace_every: int = 1  # record the energy trace every this many iterations
    final_contact_samples: int = 0  # after the last step, search this many contact sets per grasp (0: off, DexGraspNet)
    contact_search_every: int = 0  # also run that search every this many iterations (0: only after the last step)
    keep_best: bool = False  # end in each grasp's lowest-energy visited state (False: the last state, DexGraspNet)
    resolve_penetration_to_m: float = 0.0  # last phase: back grasps deeper than this out of the object (0: off)
    stop_hopeless: HopelessStopConfig = HopelessStopConfig()  # checkpoints where grasps far from the thresholds stop (none: off)

    @classmethod
    def from_schedule(cls, schedule: AnnealingSchedule, **run_options) -> "AnnealingConfig":
        """``schedule``'s values with the given run options (trace_every, final_contact_samples, ...)."""
        return cls(**{f.name: getattr(schedule, f.name) for f in dataclasses.fields(AnnealingSchedule)}, **run_options)

    def step_size_at(self, iteration: int) -> float:
        return self.step_size * self.step_size_decay ** (iteration // self.step_size_period)

    def temperature_at(self, iteration: int) -> float:
        return self.starting_temperature * self.temperature_decay ** (iteration // self.temperature_period)


@dataclass(frozen=True)
class InitConfig:
    """Where optimization from scratch starts (DexGraspNet: palm 0.2–0.3 m out, ±30°, σ 10%)."""

    distance_m: tuple[float, float] = setting((0.2, 0.3), "palm distance from the hull point", items={"minimum": 0})
    jitter_deg: float = setting(30.0, "approach tilt away from the inward normal", minimum=0, maximum=90)
    joint_sigma_fraction: float = setting(0.1, "joint noise σ as a fraction of each range", minimum=0)
    start_faces: str = setting(
        "area", "where on the hull power starts begin: area (every hull face by its area, DexGraspNet's); top_and_sides (on a "
        "table, half the starts on the faces facing up, within 30° of the table's normal, half on the others, each half by area: "
        "a tall object's top is a small share of its hull)", enum=("area", "top_and_sides"))


@dataclass(frozen=True)
class GraspTypeShares:
    """The share of each object's starts optimized as each grasp type (config ``optimize_grasps.grasp_types``; the types
    are ``optim.grasp_types``). Shares are weights, divided by their sum; a type with share 0 is not made."""

    power: float = setting(1.0, "palm toward the object, four contacts anywhere on the finger pads (DexGraspNet's)", minimum=0)
    pinch: float = setting(0.0, "precision pinch: thumb tip against index fingertip (middle fingertip optional)", minimum=0)
    tripod: float = setting(0.0, "thumb tip against index and middle fingertips", minimum=0)
    lateral: float = setting(0.0, "thumb pad against the side of the index finger's middle phalanx (key pinch)", minimum=0)
    rim: float = setting(0.0, "rim: thumb on one side of a rim or edge opposite the centroid of index, middle and ring fingertips on the other",
                         minimum=0)

    def __post_init__(self) -> None:
        for name, share in self.shares().items():
            if not (math.isfinite(share) and share >= 0):
                raise ConfigError(f"optimize_grasps.grasp_types.{name}: expected a share of at least 0, got {share}")
        if not sum(self.shares().values()) > 0:
            raise ConfigError("optimize_grasps.grasp_types: every share is 0; give at least one grasp type a positive share")

    def shares(self) -> dict[str, float]:
        """Type name -> share, as given (not normalized)."""
        return {f.name: float(getattr(self, f.name)) for f in dataclasses.fields(self)}


# Both optimizers end with contact resolution (optim.contact_resolution): the doc of their resolve_penetration_to_m.
RESOLVE_PENETRATION_DOC = ("contact resolution, the last phase: grasps deeper in the object than this (penetration measure, m) "
                           "back out of it until within it (0 = off; the lift test's start cap is 2 mm)")


# The default from-scratch schedule: DexGraspNet's shortened to 2000 steps from 0.1-0.15 m, its
# periods scaled to match (why: docs/results.md); DexGraspNet's own is config/profiles/dexgraspnet_schedule.yaml.
FROM_SCRATCH_SCHEDULE = AnnealingSchedule(iterations=2000, step_size_period=17, temperature_period=10)


@dataclass(frozen=True)
class OptimizeGraspsConfig:
    """Config section ``optimize_grasps``."""

    grasps_per_object: int = setting(
        32, "starts per object and scale (force-closure curation keeps ~1 in 8 of them as training data)", minimum=1)
    scales: tuple[float, ...] = setting(
        (0.08, 0.1, 0.12), "object scales (about the object radius in metres)", items={"exclusive_minimum": 0}, min_items=1)
    real_size: bool = setting(
        False, "objects whose files are known to be in metres (generated household objects) are optimized at their real size, "
        "as many starts as the scales give the others, instead of at the scales")
    batch_size: int = setting(
        512, "grasps optimized together (several objects per batch; results depend on it: starts and contacts are drawn in batch order)", minimum=1)
    objects_per_energy: int = setting(
        128, "objects whose energy (SDF grid, mesh, penetration points: ~10-50 MB each) is held at once: a shard with more is "
        "optimized in groups of this many objects, one after the other (0 = all at once; results depend on it only for shards "
        "of more objects, and never for `dexlite grasp`, whose draws are keyed by object)", minimum=0)
    progress_every: int = setting(100, "iterations between progress lines in the log", minimum=1, result_neutral=True)
    thresholds: EnergyThresholds = setting(
        factory=EnergyThresholds, doc="passes_energy_thresholds (DexGraspNet's success criteria)")
    grasp_types: GraspTypeShares = setting(
        factory=GraspTypeShares, doc="share of each object's starts per grasp type (weights, divided by their sum; optim/grasp_types.py): "
        "each type starts from its own pre-grasp pose and approach and draws its four contacts from its own contact template")
    init: InitConfig = setting(
        factory=lambda: InitConfig(distance_m=(0.1, 0.15)), doc="convex-hull start of power grasps (joint_sigma_fraction: of every grasp type)",
        docs={"distance_m": "palm distance from the hull point (DexGraspNet: 0.2-0.3)"})
    annealing: AnnealingSchedule = setting(
        FROM_SCRATCH_SCHEDULE, "DexGraspNet's schedule shortened to 2000 steps, its periods scaled to match (why: docs/results.md)",
        docs={"iterations": "optimizer steps (DexGraspNet: 6000)",
              "step_size_period": "iterations between step-size decays (DexGraspNet: 50 over 6000 steps)",
              "temperature_period": "iterations between temperature decays (DexGraspNet: 30 over 6000 steps)"})
    trace_every: int = setting(10, "iterations between rows of the energy trace", minimum=1)
    final_contact_samples: int = setting(
        1024, "contact sets searched per grasp after the last step (0: off, as DexGraspNet)", minimum=0)
    contact_search_every: int = setting(100, "also search every this many iterations (0: only after the last step)", minimum=0)
    keep_best: bool = setting(False, "end in the last accepted state (DexGraspNet); true: the lowest-energy visited state")
    resolve_penetration_to_m: float = setting(0.0015, RESOLVE_PENETRATION_DOC, minimum=0)
    stop_hopeless: HopelessStopConfig = setting(
        factory=lambda: HopelessStopConfig(iterations=(300, 600, 1000), max_e_fc=(4.0, 2.0, 1.0), max_e_dis_m=(1.0, 1.0, 0.02)),
        doc="grasps still far from the energy thresholds at a checkpoint stop there (default run's objects: about 1 grasp in 3 "
            "stops, 29% of the iterations saved, 1 in 60 grasps that would pass lost: docs/results.md); dexlite grasp does not "
            "lift-test them")

    def optimizer_config(self) -> AnnealingConfig:
        """The optimizer's settings for one run: the schedule with this section's run options."""
        return AnnealingConfig.from_schedule(
            self.annealing, trace_every=self.trace_every, final_contact_samples=self.final_contact_samples,
            contact_search_every=self.contact_search_every, keep_best=self.keep_best,
            resolve_penetration_to_m=self.resolve_penetration_to_m, stop_hopeless=self.stop_hopeless,
        )


# The write-up's post-optimization schedule: DexGraspNet's constants over 200 iterations.
POST_SCHEDULE = AnnealingSchedule(iterations=200)


@dataclass(frozen=True)
class PostOptimizeConfig:
    """Config section ``post_optimize`` (the write-up's post-optimization)."""

    annealing: AnnealingSchedule = setting(
        POST_SCHEDULE, "the optimizer's schedule for random starts (the write-up's: DexGraspNet's over 200 steps)")
    energy_weights: EnergyWeights = setting(
        factory=EnergyWeights, doc="E_post = fc·E_fc + dis·E_dis + pen·E_pen + spen·E_spen + joints·E_joints (+ table·E_table on a table)")
    energy_point_spacing_m: float = setting(
        0.004, "mean spacing of E_pen's object surface points at the grasp's scale, m (the judged depth: 2 mm)", exclusive_minimum=0)
    start_contact_samples: int = setting(
        64, "a sampled grasp starts from the best of this many near-surface pad 4-sets (0 = nearest four pads)", minimum=0)
    final_contact_samples: int = setting(
        64, "after the last step, the best of this many contact sets is kept (0 = off, DexGraspNet)", minimum=0)
    keep_best: bool = setting(
        True, "end each grasp in its lowest-E_post visited state, not the last: at T0 = 18 the walk accepts nearly every step "
        "and wanders away from grasps that hold")
    learned_start_temperature: float = setting(
        0.5, "CVAE starts (already close to a grasp) run with this T0 and learned_start_step_size instead: at T0 18 the walk "
        "accepts nearly every step and wanders off", exclusive_minimum=0)
    learned_start_step_size: float = setting(
        0.002, "... and this step size at iteration 0 (18 / 0.005: the write-up's schedule)", exclusive_minimum=0)
    budget_iterations: tuple[int, ...] = setting(
        (0, 25, 50, 100, 200), "poses kept after these iterations and lift-tested (the budget curve)", items={"minimum": 0},
        unique_items=True)
    batch_size: int = setting(1024, "grasps per optimizer batch (a shard is cut into batches of this size)", minimum=1)
    objects_per_energy: int = setting(
        128, "objects whose energy (SDF grid, mesh, penetration points: ~10-50 MB each) is held at once: a shard (or the meshes "
        "of one `dexlite grasp`) with more is refined in groups of this many objects, one after the other (0 = all at once; "
        "results depend on it only when there are more objects)", minimum=0)
    random_baseline: bool = setting(True, "also post-optimize from random convex-hull starts (same budget, held-out objects)")
    random_init: InitConfig = setting(factory=InitConfig, doc="the random starts (DexGraspNet's)")
    resolve_penetration_to_m: float = setting(0.0015, RESOLVE_PENETRATION_DOC, minimum=0)
    stop_hopeless: HopelessStopConfig = setting(
        factory=lambda: HopelessStopConfig(iterations=(25, 50, 100), max_e_fc=(16.0, 8.0, 4.0), max_e_dis_m=(0.1, 0.05, 0.05)),
        doc="sampled grasps still far from the energy thresholds at a checkpoint stop there and are not backed out of the object "
            "(household model's samples: about 2 in 5 stop, 30% of the iterations saved, 1 to 3 in 100 grasps that would hold "
            "lost: docs/results.md); dexlite grasp does not lift-test them")

    def optimizer_config(self, learned_start: bool = False) -> AnnealingConfig:
        """The optimizer's settings: ``annealing`` for random starts; for learned (CVAE) starts the same
        with the close-start temperature and step size, and ``stop_hopeless`` (its limits are those of learned starts).
        The energy is traced at every iteration."""
        schedule = self.annealing
        if learned_start:
            schedule = dataclasses.replace(schedule, starting_temperature=self.learned_start_temperature, step_size=self.learned_start_step_size)
        return AnnealingConfig.from_schedule(
            schedule, trace_every=1, final_contact_samples=self.final_contact_samples, keep_best=self.keep_best,
            resolve_penetration_to_m=self.resolve_penetration_to_m, stop_hopeless=self.stop_hopeless if learned_start else HopelessStopConfig(),
        )

    def budget(self) -> tuple[int, ...]:
        """The budget-curve iterations within this run's length."""
        return tuple(sorted(i for i in set(self.budget_iterations) if 0 <= i <= self.annealing.iterations))
