"""DexGraspNet's annealed grasp optimizer, batched over every grasp at once.

Each iteration of ``optimize`` has three parts, each its own piece here:

* step (``RMSPropProposal``): a gradient step on the state [palm translation (m), palm
  rotation in 6D form, joint angles (rad)] scaled RMSProp-style, plus each contact index
  re-drawn with probability ``contact_switch_probability``, and the energy of the result.
  It is DexGraspNet's variant of RMSProp, kept on purpose because it gives more passing
  grasps than the standard form: the running mean puts weight ``mu`` on the NEW squared
  gradient; by default each grasp keeps its own (``rmsprop_statistic`` "grasp"), DexGraspNet
  averages it over the batch ("batch").
* accept (``metropolis_accept``, ``WalkState.where``, ``KeepBest``): each proposal is
  accepted with Metropolis probability exp((E_old − E_new)/T), T = T0·decay^⌊k/period⌋; a
  rejected grasp keeps its old pose, contacts and gradient. With ``keep_best`` each grasp
  ends in the lowest-energy state it visited rather than the last one, because at a high
  temperature the walk accepts almost every proposal and can leave a good grasp.
* track (``Tracker``): the energy trace of the kept state, its terms, pose snapshots at
  chosen iterations and the acceptance counts.

With ``resolve_penetration_to_m``, the run ends with contact resolution
(``optim.contact_resolution``): grasps deeper in the object than that back out of it (not those
stopped as hopeless, ``stop_hopeless``), and the reported terms are those of the resolved poses.
``penetration_mm`` is always the judged depth (against the mesh), not the grid's.

Optionally (``final_contact_samples``), a last search over many contact sets for the final
poses picks the best (``GraspEnergy.best_contacts``): the random walk over contact indices
rarely lands on the best set once T is low. With ``contact_search_every`` the same search
also runs during the run, so the gradient then pulls the best contacts found onto the
surface (it never raises the energy). Results come back as the stored 28-vector pose.

With ``contact_slots`` (a grasp type's contact template, ``energy.contact_slots``) every draw of a contact, at the
start, in the walk and in the searches, is among the candidates its slot allows; without, among all 140 pads.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import torch

from dexlite_pipeline.energy.contact_slots import ContactSlots
from dexlite_pipeline.energy.grasp_energy import CONTACT_COUNT, EnergyResult, GraspEnergy
from dexlite_pipeline.hand.model import JOINTS, ROTATION, TRANSLATION
from dexlite_pipeline.hand.rotation import euler_xyz_to_matrix, matrix_to_euler_xyz, matrix_to_rot6d, rot6d_to_matrix
from dexlite_pipeline.optim.config import AnnealingConfig
from dexlite_pipeline.optim.contact_resolution import penetration_depth_m, resolve_contacts
from dexlite_pipeline.optim.grasp_random import GraspRandom

log = logging.getLogger(__name__)

# The state's columns: palm translation, palm rotation (6D), and the joints to the end (22 for the Shadow Hand, J for a
# hand from its MJCF), as a stored pose's joints are its columns from ``JOINTS.start`` on.
_T, _R6, _Q = slice(0, 3), slice(3, 9), slice(9, None)


@dataclass
class OptimizationResult:
    """Final state per grasp, its energy terms, and the energy trace (recorded iterations, B)."""

    hand_pose: torch.Tensor  # (B, 28) stored form
    contact_index: torch.Tensor  # (B, 4)
    terms: dict[str, torch.Tensor]  # (B,) each, at the final state
    total: torch.Tensor  # (B,)
    penetration_mm: torch.Tensor
    contact_distance_mm: torch.Tensor
    trace: torch.Tensor  # (len(trace_iterations), B) total energy of the kept state (the best so far with keep_best;
    # last row after the contact search)
    trace_iterations: torch.Tensor  # (T,) iteration numbers of the trace rows (0 = initial)
    term_traces: dict[str, torch.Tensor]  # name -> (T, B): each energy term of the kept state at the trace rows
    acceptance_rate: torch.Tensor  # (B,) fraction of proposals accepted
    seconds: float
    snapshots: dict[int, torch.Tensor] | None = None  # iteration -> (B, 28) kept pose after it (``snapshot_iterations``
    # of ``optimize``; iteration 0 is the start)
    stopped_at_iteration: torch.Tensor | None = None  # (B,) iteration a hopeless grasp stopped at (0: it walked every iteration)


def pose_to_state(hand_pose: torch.Tensor) -> torch.Tensor:
    """(B, 28) stored pose -> (B, 31) optimizer state [t, rot6d, joints] ((B, 6 + J) -> (B, 9 + J) for any hand)."""
    rot6d = matrix_to_rot6d(euler_xyz_to_matrix(hand_pose[:, ROTATION]))
    return torch.cat([hand_pose[:, TRANSLATION], rot6d, hand_pose[:, JOINTS.start :]], dim=1)


def state_to_pose(state: torch.Tensor) -> torch.Tensor:
    """(B, 31) optimizer state -> (B, 28) stored pose ((B, 9 + J) -> (B, 6 + J) for any hand)."""
    euler = matrix_to_euler_xyz(rot6d_to_matrix(state[:, _R6]))
    return torch.cat([state[:, _T], euler, state[:, _Q]], dim=1)


def random_contacts(batch: int, candidate_count: int, generator: torch.Generator, device) -> torch.Tensor:
    """(B, 4) contact indices drawn uniformly among the candidates."""
    return torch.randint(candidate_count, (batch, CONTACT_COUNT), generator=generator).to(device)


class StateEnergy:
    """The energy of optimizer states (B, 31) at given contacts, with its gradient w.r.t. the state."""

    def __init__(self, energy: GraspEnergy, object_index: torch.Tensor, scale: torch.Tensor) -> None:
        self.energy = energy
        self.object_index = object_index
        self.scale = scale

    def take(self, rows: torch.Tensor) -> "StateEnergy":
        """The same energy for the grasps at ``rows`` only."""
        return StateEnergy(self.energy, self.object_index[rows], self.scale[rows])

    def __call__(self, state: torch.Tensor, contacts: torch.Tensor) -> "WalkState":
        """Evaluate at ``state``; NaN and ±inf in the gradient become 0, as one grasp's NaN would otherwise
        stall it (and, with the batch statistic, reach every grasp through the RMSProp mean)."""
        x = state.detach().requires_grad_(True)
        result = self.energy(
            palm_rot=rot6d_to_matrix(x[:, _R6]), palm_t=x[:, _T], joints=x[:, _Q],
            object_index=self.object_index, scale=self.scale, contact_index=contacts,
        )
        (grad,) = torch.autograd.grad(result.total.sum(), x)
        return WalkState(state, contacts, result.total.detach(), result, torch.nan_to_num(grad, nan=0.0, posinf=0.0, neginf=0.0))


@dataclass
class WalkState:
    """One state per grasp of the walk: where it is, its energy and (for the walking chain) its gradient."""

    state: torch.Tensor  # (B, 31) [palm translation (m), palm rotation 6D, joints (rad)]
    contacts: torch.Tensor  # (B, 4) contact candidate indices
    total: torch.Tensor  # (B,) total energy, detached
    result: EnergyResult | _Kept  # the terms and diagnostics at this state
    grad: torch.Tensor | None = None  # (B, 31) d total / d state; None where no step is taken from it

    def where(self, mask: torch.Tensor, other: "WalkState") -> "WalkState":
        """Per grasp, ``other`` where ``mask`` (B,) is True, else this state."""
        grad = None if self.grad is None or other.grad is None else torch.where(mask[:, None], other.grad, self.grad)
        return WalkState(
            torch.where(mask[:, None], other.state, self.state),
            torch.where(mask[:, None], other.contacts, self.contacts),
            torch.where(mask, other.total, self.total),
            _select(mask, other.result, self.result),
            grad,
        )

    def take(self, rows: torch.Tensor) -> "WalkState":
        """The grasps at ``rows`` (index tensor) only."""
        result = _Kept({k: v.detach()[rows] for k, v in self.result.terms.items()}, self.result.penetration_mm[rows],
                       self.result.contact_distance_mm[rows])
        return WalkState(self.state[rows], self.contacts[rows], self.total[rows], result, None if self.grad is None else self.grad[rows])


class RMSPropProposal:
    """The proposal step: an RMSProp-scaled gradient step plus random contact switches, evaluated.

    The running mean of the squared gradient weights the NEW value by ``rmsprop_mu``; with
    ``rmsprop_statistic`` "batch" it is one value per state coordinate, the mean over the batch's
    grasps (DexGraspNet), with "grasp" each grasp keeps its own.
    """

    def __init__(self, config: AnnealingConfig, evaluate: StateEnergy, candidate_count: int, draws: "Draws", like: torch.Tensor) -> None:
        self.config = config
        self.evaluate = evaluate
        self.candidate_count = candidate_count
        self.draws = draws
        self.per_grasp = config.rmsprop_statistic == "grasp"
        self.square_avg = torch.zeros(like.shape if self.per_grasp else like.shape[1], dtype=like.dtype, device=like.device)

    def take(self, rows: torch.Tensor) -> None:
        """Go on with the grasps at ``rows`` only (each keeps its own statistic; the batch statistic stays as it is)."""
        self.evaluate = self.evaluate.take(rows)
        self.draws = self.draws.take(rows)
        if self.per_grasp:
            self.square_avg = self.square_avg[rows]

    def __call__(self, walk: WalkState, iteration: int) -> WalkState:
        """The proposal for ``iteration`` (1-based) from ``walk``; draws the switch mask, then the new indices."""
        config = self.config
        square = walk.grad.square() if self.per_grasp else walk.grad.square().mean(0)
        self.square_avg = config.rmsprop_mu * square + (1 - config.rmsprop_mu) * self.square_avg
        step = config.step_size_at(iteration - 1) * walk.grad / (self.square_avg.sqrt() + config.rmsprop_eps)
        proposal = walk.state - step
        switch = self.draws.switches(iteration, config.contact_switch_probability)
        redrawn = self.draws.contacts(iteration, self.candidate_count)
        return self.evaluate(proposal, torch.where(switch, redrawn, walk.contacts))


class Draws:
    """The walk's random draws: from the run's generator in batch order, or, with ``random`` (``GraspRandom``),
    from each grasp's own stream, so that a grasp walks the same alone or in any batch. With ``slots``
    (``ContactSlots``) each contact is drawn among its slot's candidates (one uniform per contact either way)."""

    def __init__(self, batch: int, generator: torch.Generator, device, random: GraspRandom | None = None,
                 slots: ContactSlots | None = None) -> None:
        self.batch, self.generator, self.device, self.random, self.slots = batch, generator, device, random, slots

    def take(self, rows: torch.Tensor) -> "Draws":
        """The draws of the grasps at ``rows`` only (their own streams with ``random``)."""
        return Draws(len(rows), self.generator, self.device, None if self.random is None else self.random.take(rows),
                     None if self.slots is None else self.slots.take(rows))

    def contacts(self, iteration: int, candidate_count: int) -> torch.Tensor:
        """(B, 4) contact indices drawn uniformly among the candidates (iteration 0: the start)."""
        if self.slots is not None:
            if self.random is None:
                uniform = torch.rand(self.batch, CONTACT_COUNT, generator=self.generator, dtype=torch.float64)
            else:
                uniform = self.random.uniform(iteration, GraspRandom.INITIAL_CONTACTS if iteration == 0 else GraspRandom.REDRAW, CONTACT_COUNT)
            return self.slots.draw(uniform).to(self.device)
        if self.random is None:
            return random_contacts(self.batch, candidate_count, self.generator, self.device)
        stream = GraspRandom.INITIAL_CONTACTS if iteration == 0 else GraspRandom.REDRAW
        return self.random.integers(candidate_count, iteration, stream, CONTACT_COUNT).to(self.device)

    def switches(self, iteration: int, probability: float) -> torch.Tensor:
        """(B, 4) bool: which contacts are re-drawn."""
        if self.random is None:
            return (torch.rand(self.batch, CONTACT_COUNT, generator=self.generator) < probability).to(self.device)
        return (self.random.uniform(iteration, GraspRandom.SWITCH, CONTACT_COUNT) < probability).to(self.device)

    def acceptance(self, iteration: int) -> torch.Tensor:
        """(B,) uniforms for the Metropolis test."""
        if self.random is None:
            return torch.rand(self.batch, generator=self.generator).to(self.device)
        return self.random.uniform(iteration, GraspRandom.ACCEPT, 1)[:, 0].to(self.device)

    def contact_search(self, iteration: int):
        """The draw of ``GraspEnergy.best_contacts``: None (its generator) or a weighted draw from the grasps' streams."""
        if self.random is None:
            return None
        return lambda weight, count: self.random.weighted(weight, iteration, GraspRandom.CONTACT_SEARCH, count)


def metropolis_accept(old_total: torch.Tensor, new_total: torch.Tensor, temperature: float, uniform: torch.Tensor) -> torch.Tensor:
    """(B,) bool: accept each proposal with probability min(1, exp((E_old − E_new)/T)); ``uniform`` (B,), one draw per grasp."""
    return uniform.to(old_total.dtype) < torch.exp((old_total - new_total) / temperature)


class KeepBest:
    """The lowest-energy state each grasp has visited (ties keep the earlier one)."""

    def __init__(self, start: WalkState) -> None:
        self.best = replace(start, grad=None)

    def update(self, walk: WalkState) -> None:
        self.best = self.best.where(walk.total < self.best.total, replace(walk, grad=None))

    def take(self, rows: torch.Tensor) -> None:
        self.best = self.best.take(rows)


def search_contacts(energy: GraspEnergy, walk: WalkState, evaluate: StateEnergy, samples: int, generator: torch.Generator, draw=None,
                    slots: ContactSlots | None = None) -> WalkState:
    """The walk re-evaluated at the best of ``samples`` contact sets per grasp for its current poses (never worse).

    Run every ``contact_search_every`` iterations, so the next gradient steps pull the chosen contacts onto the surface.
    ``slots``: the grasps' contact templates (None: any pad).
    """
    contacts = energy.best_contacts(state_to_pose(walk.state), evaluate.object_index, evaluate.scale, walk.contacts, samples, generator, draw=draw,
                                    slots=slots)
    return evaluate(walk.state, contacts)


class Tracker:
    """What ``optimize`` reports besides the final state: energy and term traces, snapshots, acceptance counts.

    Rows are the run's grasps; once hopeless grasps have stopped (``optimize``), ``active`` names the rows still
    walking, and a stopped grasp's trace and snapshots stay where it stopped.
    """

    def __init__(self, config: AnnealingConfig, start: WalkState, init_pose: torch.Tensor, snapshot_iterations: tuple[int, ...]) -> None:
        self.config = config
        self.snapshot_iterations = snapshot_iterations
        self.accepted = torch.zeros(start.total.shape[0], dtype=torch.long, device=start.total.device)
        self.trace = [start.total.clone()]
        self.trace_iterations = [0]
        self.term_traces = {name: [value.detach().clone()] for name, value in start.result.terms.items()}
        self.snapshots = {0: init_pose.detach().to(start.state.device, start.state.dtype).clone()} if 0 in snapshot_iterations else {}
        self.stopped_pose = torch.zeros(init_pose.shape, dtype=start.state.dtype, device=start.state.device)  # stopped grasps' kept poses

    def count(self, accept: torch.Tensor, active: torch.Tensor) -> None:
        self.accepted[active] += accept.long()

    def record(self, iteration: int, kept: WalkState, active: torch.Tensor) -> None:
        """After ``iteration``: a trace row every ``trace_every`` iterations and at the last, a snapshot if asked."""
        if iteration % self.config.trace_every == 0 or iteration == self.config.iterations:
            self.trace.append(_scatter(self.trace[-1], active, kept.total))
            self.trace_iterations.append(iteration)
            for name, value in kept.result.terms.items():
                self.term_traces[name].append(_scatter(self.term_traces[name][-1], active, value.detach()))
        if iteration in self.snapshot_iterations:
            self.snapshots[iteration] = _scatter(self.stopped_pose, active, state_to_pose(kept.state).detach())

    def stop(self, rows: torch.Tensor, state: torch.Tensor) -> None:
        """The grasps at run rows ``rows`` stop walking in optimizer states ``state``."""
        self.stopped_pose[rows] = state_to_pose(state).detach()

    def replace_last(self, total: torch.Tensor, terms: dict[str, torch.Tensor]) -> None:
        """Overwrite the last trace row (after the final contact search changed the final state's energy)."""
        self.trace[-1] = total.clone()
        for name, value in terms.items():
            self.term_traces[name][-1] = value.detach().clone()

    def acceptance_rate(self, dtype: torch.dtype) -> torch.Tensor:
        return self.accepted.to(dtype) / max(self.config.iterations, 1)


def _scatter(full: torch.Tensor, rows: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    """A copy of ``full`` with ``values`` at ``rows`` (just ``values`` while every grasp is still walking)."""
    if len(rows) == full.shape[0]:
        return values.clone()
    out = full.clone()
    out[rows] = values
    return out


def hopeless(kept: WalkState, limits: tuple[float, float]) -> torch.Tensor:
    """(B,) bool: grasps whose kept state is too far from the energy thresholds to be worth more steps: E_fc or E_dis
    above ``limits`` (max E_fc, max E_dis in m; ``HopelessStopConfig``)."""
    max_e_fc, max_e_dis_m = limits
    terms = kept.result.terms
    return (terms["E_fc"].detach() > max_e_fc) | (terms["E_dis"].detach() > max_e_dis_m)


def optimize(
    energy: GraspEnergy,
    init_pose: torch.Tensor,
    object_index: torch.Tensor,
    scale: torch.Tensor,
    config: AnnealingConfig,
    generator: torch.Generator,
    contact_index: torch.Tensor | None = None,
    progress: Callable[[int, torch.Tensor], None] | None = None,
    progress_every: int = 100,
    snapshot_iterations: tuple[int, ...] = (),
    random: GraspRandom | None = None,
    contact_slots: ContactSlots | None = None,
) -> OptimizationResult:
    """Run the annealed optimizer on a batch of grasps from ``init_pose`` (B, 28).

    ``contact_index`` None draws the initial contacts uniformly (DexGraspNet's start);
    ``generator`` (a CPU ``torch.Generator``) makes the run deterministic for a seed.
    ``progress(iteration, total_energy)`` is called every ``progress_every`` iterations
    with the walking chain's energy.
    ``snapshot_iterations``: also return the kept pose (the best so far with ``keep_best``)
    after each of these iterations, for budget curves. ``random`` (``GraspRandom``): the walk's
    draws from each grasp's own stream instead of ``generator``; with ``rmsprop_statistic`` "grasp"
    (and the CPU's compiled energy) a grasp then refines the same alone or in any batch. ``contact_slots``
    (``ContactSlots``, B grasps): each grasp's contacts are drawn and searched among its template's candidates only
    (the initial contacts too, unless ``contact_index`` is given); None: among all pads.
    """
    started = time.process_time()  # CPU seconds of this process (all its threads): costs stay true on a shared machine
    device = energy.device
    batch = init_pose.shape[0]
    candidate_count = len(energy.hand.contact_link)
    evaluate = StateEnergy(energy, object_index, scale)
    state = pose_to_state(init_pose.to(device, energy.hand.dtype)).detach()
    draws = Draws(batch, generator, device, random, contact_slots)
    contacts = draws.contacts(0, candidate_count) if contact_index is None else contact_index.to(device)

    walk = evaluate(state, contacts)
    propose = RMSPropProposal(config, evaluate, candidate_count, draws, like=state)
    best = KeepBest(walk) if config.keep_best else None
    tracker = Tracker(config, walk, init_pose, snapshot_iterations)
    searching = config.final_contact_samples and config.contact_search_every
    active = torch.arange(batch, device=device)  # the run's rows still walking
    stopped_at = torch.zeros(batch, dtype=torch.long, device=device)  # iteration a hopeless grasp stopped at (0: walked to the end)
    stopped_state, stopped_contacts = torch.zeros_like(state), torch.zeros_like(contacts)  # where they stopped, by run row
    kept = walk
    for iteration in range(1, config.iterations + 1):
        if not len(active):  # every grasp has stopped: the traces stay where they are
            tracker.record(iteration, kept, active)
            continue
        proposal = propose(walk, iteration)
        accept = metropolis_accept(walk.total, proposal.total, config.temperature_at(iteration), propose.draws.acceptance(iteration))
        tracker.count(accept, active)
        walk = walk.where(accept, proposal)
        if searching and iteration % config.contact_search_every == 0 and iteration < config.iterations:
            walk = search_contacts(energy, walk, propose.evaluate, config.final_contact_samples, generator, propose.draws.contact_search(iteration),
                                   propose.draws.slots)
        if best is not None:
            best.update(walk)
        kept = walk if best is None else best.best
        tracker.record(iteration, kept, active)
        if progress is not None and iteration % progress_every == 0:
            progress(iteration, walk.total)
        limits = config.stop_hopeless.limits_at(iteration)
        stopping = hopeless(kept, limits) if limits is not None else None
        if stopping is not None and bool(stopping.any()):
            rows = active[stopping]
            stopped_at[rows], stopped_state[rows], stopped_contacts[rows] = iteration, kept.state[stopping], kept.contacts[stopping]
            tracker.stop(rows, kept.state[stopping])
            going_on = torch.nonzero(~stopping).squeeze(1)
            active, walk = active[going_on], walk.take(going_on)
            propose.take(going_on)
            if best is not None:
                best.take(going_on)
            kept = walk if best is None else best.best

    final = walk if best is None else best.best
    if len(active) < batch:  # stopped grasps end where they stopped, the others where their walk ended
        stopped_state[active], stopped_contacts[active] = final.state, final.contacts
        with torch.no_grad():
            result = energy(state_to_pose(stopped_state), object_index=object_index, scale=scale, contact_index=stopped_contacts)
        final = WalkState(stopped_state, stopped_contacts, result.total.detach(), result)
    hand_pose = state_to_pose(final.state).detach()
    contacts, total, result = final.contacts, final.total, final.result
    if config.final_contact_samples > 0:
        contacts = energy.best_contacts(hand_pose, object_index, scale, contacts, config.final_contact_samples, generator,
                                        draw=draws.contact_search(config.iterations + 1), slots=contact_slots)
        with torch.no_grad():
            result = energy(hand_pose, object_index=object_index, scale=scale, contact_index=contacts)
        total = result.total.detach()
        tracker.replace_last(total, result.terms)
    resolving = config.resolve_penetration_to_m > 0 and len(active) > 0
    if resolving:
        # Only the grasps that walked to the end: a grasp stopped as hopeless is not worth backing out of the object.
        resolved = resolve_contacts(energy, hand_pose[active], object_index[active], scale[active], config.resolve_penetration_to_m)
        if bool((resolved.steps > 0).any()):
            hand_pose = hand_pose.clone()
            hand_pose[active] = resolved.hand_pose
            with torch.no_grad():
                result = energy(hand_pose, object_index=object_index, scale=scale, contact_index=contacts)
            total = result.total.detach()
            tracker.replace_last(total, result.terms)
    if resolving and len(active) == batch:
        depth = resolved.depth_m
    else:  # no resolution, or some grasps stopped: every grasp's depth from one pass
        depth = penetration_depth_m(energy, hand_pose, object_index, scale)
    return OptimizationResult(
        hand_pose=hand_pose,
        contact_index=contacts,
        terms={k: v.detach() for k, v in result.terms.items()},
        total=total,
        penetration_mm=depth * 1000.0,
        contact_distance_mm=result.contact_distance_mm,
        trace=torch.stack(tracker.trace),
        trace_iterations=torch.as_tensor(tracker.trace_iterations),
        term_traces={name: torch.stack(values) for name, values in tracker.term_traces.items()},
        acceptance_rate=tracker.acceptance_rate(final.state.dtype),
        seconds=time.process_time() - started,
        snapshots=tracker.snapshots,
        stopped_at_iteration=stopped_at,
    )


class _Kept:
    """The per-grasp diagnostics of the kept state (detached), updated on acceptance."""

    def __init__(self, terms, penetration_mm, contact_distance_mm):
        self.terms = terms
        self.penetration_mm = penetration_mm
        self.contact_distance_mm = contact_distance_mm


def _select(accept: torch.Tensor, new, old) -> _Kept:
    """Terms and diagnostics of ``new`` where ``accept`` (B,) is True, else of ``old`` (detached)."""
    terms = {k: torch.where(accept, new.terms[k].detach(), old.terms[k].detach()) for k in new.terms}
    return _Kept(
        terms,
        torch.where(accept, new.penetration_mm, old.penetration_mm),
        torch.where(accept, new.contact_distance_mm, old.contact_distance_mm),
    )
