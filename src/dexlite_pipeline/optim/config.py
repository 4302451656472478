"""The optimizer's config types: the annealing schedule, the start poses, sections ``optimize_grasps`` and ``post_optimize``.

A leaf of the config tree (``settings``): it imports no optimizer code, so a stage's code hash
(``codehash``) covers these shapes without the computation. ``AnnealingSchedule`` is the one
schedule type (``optimize_grasps.annealing``, ``post_optimize.annealing``) and ``InitConfig`` the one
start type (``optimize_grasps.init``, ``post_optimize.random_init``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from dexlite_pipeline.energy.config import EnergyThresholds, EnergyWeights


@dataclass(frozen=True)
class AnnealingSchedule:
    """The annealing schedule: step size, temperature and their decay (config ``optimize_grasps.annealing``,
    ``post_optimize.annealing``). Defaults: DexGraspNet's constants (6000 steps from scratch)."""

    iterations: int = 6000
    step_size: float = 0.005  # scaled-gradient step at iteration 0
    step_size_decay: float = 0.95  # step size × this every step_size_period iterations
    step_size_period: int = 50
    rmsprop_mu: float = 0.98  # weight of the NEW batch-mean squared gradient (DexGraspNet)
    rmsprop_eps: float = 1e-8
    contact_switch_probability: float = 0.5  # per contact and iteration
    starting_temperature: float = 18.0  # Metropolis T0 (energy units)
    temperature_decay: float = 0.95  # T × this every temperature_period iterations
    temperature_period: int = 30


@dataclass(frozen=True)
class AnnealingConfig(AnnealingSchedule):
    """Everything one optimizer run needs: the schedule plus what the run records and how it ends."""

    trace_every: int = 1  # record the energy trace every this many iterations
    final_contact_samples: int = 0  # after the last step, search this many contact sets per grasp (0: off, DexGraspNet)
    contact_search_every: int = 0  # also run that search every this many iterations (0: only after the last step)
    keep_best: bool = False  # end in each grasp's lowest-energy visited state (False: the last state, DexGraspNet)
    resolve_penetration_to_m: float = 0.0  # last phase: back grasps deeper than this out of the object (0: off)

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

    distance_m: tuple[float, float] = (0.2, 0.3)  # palm origin distance from the hull point
    jitter_deg: float = 30.0  # tilt of the approach away from the inward normal
    joint_sigma_fraction: float = 0.1  # joint noise σ as a fraction of the joint range


# The default from-scratch schedule: DexGraspNet's shortened to 2000 steps from 0.1-0.15 m, its
# periods scaled to match (why: docs/results.md); DexGraspNet's own is config/profiles/dexgraspnet_schedule.yaml.
FROM_SCRATCH_SCHEDULE = AnnealingSchedule(iterations=2000, step_size_period=17, temperature_period=10)


@dataclass(frozen=True)
class OptimizeGraspsConfig:
    """Config section ``optimize_grasps``."""

    grasps_per_object: int = 32  # starts per object and scale
    scales: tuple[float, ...] = (0.08, 0.1, 0.12)  # object scales, about the object radius in metres
    batch_size: int = 512  # grasps optimized together (changes results: the step uses batch statistics)
    progress_every: int = 100  # iterations between progress lines in the log
    thresholds: EnergyThresholds = field(default_factory=EnergyThresholds)
    init: InitConfig = field(default_factory=lambda: InitConfig(distance_m=(0.1, 0.15)))
    annealing: AnnealingSchedule = FROM_SCRATCH_SCHEDULE
    trace_every: int = 10  # iterations between rows of the energy trace
    final_contact_samples: int = 1024  # contact sets searched per grasp after the last step (0: off, DexGraspNet)
    contact_search_every: int = 100  # also search every this many iterations (0: only after the last step)
    keep_best: bool = False  # end in the last accepted state (DexGraspNet); true: the lowest-energy visited state
    resolve_penetration_to_m: float = 0.0015  # contact resolution: back grasps deeper than this out (m; 0: off)

    def optimizer_config(self) -> AnnealingConfig:
        """The optimizer's settings for one run: the schedule with this section's run options."""
        return AnnealingConfig.from_schedule(
            self.annealing, trace_every=self.trace_every, final_contact_samples=self.final_contact_samples,
            contact_search_every=self.contact_search_every, keep_best=self.keep_best,
            resolve_penetration_to_m=self.resolve_penetration_to_m,
        )


# The write-up's post-optimization schedule: DexGraspNet's constants over 200 iterations.
POST_SCHEDULE = AnnealingSchedule(iterations=200)


@dataclass(frozen=True)
class PostOptimizeConfig:
    """Config section ``post_optimize`` (the write-up's post-optimization)."""

    annealing: AnnealingSchedule = POST_SCHEDULE  # the random starts' schedule (DexGraspNet's, 200 steps)
    energy_weights: EnergyWeights = field(default_factory=EnergyWeights)  # E_post = Σ weight · term
    energy_point_spacing_m: float = 0.004  # mean spacing of E_pen's object surface points at the grasp's scale, m
    start_contact_samples: int = 64  # sampled grasps start from the best of this many near-surface 4-sets (0: nearest pads)
    final_contact_samples: int = 64  # after the last step, keep the best of this many contact sets (0: off)
    keep_best: bool = True  # return each grasp's lowest-E_post visited state instead of the last one
    learned_start_temperature: float = 0.5  # T0 for CVAE starts, which are already close: few uphill moves accepted
    learned_start_step_size: float = 0.002  # step size at iteration 0 for CVAE starts
    budget_iterations: tuple[int, ...] = (0, 25, 50, 100, 200)  # poses kept after these iterations for the budget curve
    batch_size: int = 1024  # grasps per optimizer batch (a shard is cut into batches of this size)
    random_baseline: bool = True  # also run the random-init baseline (held-out objects' grasps)
    random_init: InitConfig = field(default_factory=InitConfig)
    resolve_penetration_to_m: float = 0.0015  # contact resolution: back grasps deeper than this out (m; 0: off)

    def optimizer_config(self, learned_start: bool = False) -> AnnealingConfig:
        """The optimizer's settings: ``annealing`` for random starts; for learned (CVAE) starts the same
        with the close-start temperature and step size. The energy is traced at every iteration."""
        schedule = self.annealing
        if learned_start:
            schedule = dataclasses.replace(schedule, starting_temperature=self.learned_start_temperature, step_size=self.learned_start_step_size)
        return AnnealingConfig.from_schedule(
            schedule, trace_every=1, final_contact_samples=self.final_contact_samples, keep_best=self.keep_best,
            resolve_penetration_to_m=self.resolve_penetration_to_m,
        )

    def budget(self) -> tuple[int, ...]:
        """The budget-curve iterations within this run's length."""
        return tuple(sorted(i for i in set(self.budget_iterations) if 0 <= i <= self.annealing.iterations))
