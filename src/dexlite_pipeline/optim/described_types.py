"""Grasp types of a hand read from its MJCF: contact templates and pre-grasp poses derived from its description.

The Shadow Hand's templates are written out in ``optim.grasp_types``. Any other hand (``hand.described``) gets the
precision types its fingers allow, derived from its description alone, so a user's own hand has them too:

- **Thumb and fingers**: the thumb is the description's one opposing finger (``HandDescription.opposing``); the other
  fingers are ordered along their row from the index finger, the end of the row (of the two fingers whose base links
  lie farthest apart at the zero joint vector, the one nearer the thumb's base), by their base's distance from the
  index finger's. A hand without exactly one opposing finger, or without two more fingers, has power grasps only.
- **A finger's tip group**: the candidates on its last jointed link and on the fixed links below it (Allegro's
  ``ff_distal`` and ``ff_tip``, LEAP's ``if_ds``): where fingertips touch in a precision grasp.
- **Templates** (the four force-closure contacts, as the Shadow Hand's): pinch (thumb, thumb, index, index or middle),
  two fingers at least; tripod (thumb, thumb, index, middle), two at least; rim (thumb, thumb, index or the third
  finger, middle), three at least: the thumb on one side of a wall, three fingertips on the other. Lateral needs
  candidates on the side of the index finger, which a description does not derive: not offered.
- **Pre-grasp poses** (aperture, closed, wide; ``GraspType``): fitted by gradient descent on the joints from the
  description's kinematics at first use, the same for every run: the thumb's tip group and the mean of the finger-side
  tip groups ``opening_m`` apart, each side's mean pad normal facing the other side, no self-penetration (E_spen), the
  fingers that take no part curled (their flexion joints ``CURL_FRACTION`` of the way to their flexion limit, the limit of
  larger magnitude, as ``hand.derive`` reads flexion; joints of symmetric range at 0). Closed and wide are fitted from the
  aperture, so every blend between them opens steadily.

The start rule, the distances and the share of starts from above are the Shadow Hand's (``optim.grasp_types``): they
are about the object and the table, not the hand.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.energy.contact_slots import CONTACT_COUNT
from dexlite_pipeline.energy.terms import SelfPenetrationTerm

# A finger that takes no part in a precision type: each flexion joint this share of the way to its flexion limit.
CURL_FRACTION = 0.7
# Participating fingers and the thumb start the fit this share of the way to their flexion limits.
FIT_START_FRACTION = 0.3
# Openings between the thumb's and the fingers' tip groups (m): the aperture, nearly closed and wide, per type (the
# Shadow Hand's templates open about as far: optim.grasp_types).
OPENINGS_M = {"pinch": (0.07, 0.02, 0.10), "tripod": (0.06, 0.025, 0.10), "rim": (0.06, 0.024, 0.10)}
# Fit: Adam steps and rate (rad), and the weights of its terms (opening error per 5 mm, facing, E_spen per metre,
# distance from the fit's start per radian).
FIT_STEPS = 400
FIT_RATE = 0.02
OPENING_SCALE_M = 0.005
FACING_WEIGHT = 2.0
SPEN_WEIGHT = 200.0
STAY_WEIGHT = 0.01


@dataclass(frozen=True)
class HandFingers:
    """What the templates need of a described hand: the thumb's and the other fingers' tip groups (link names, index
    finger first), each finger's joints (indices) and its flexion limits (rad, one per joint; 0 for a joint of symmetric
    range)."""

    thumb_tip: tuple[str, ...]
    finger_tips: tuple[tuple[str, ...], ...]
    thumb_joints: tuple[int, ...]
    finger_joints: tuple[tuple[int, ...], ...]
    flexion_limit: tuple[float, ...]


def _tip_group(description, finger: tuple[str, ...]) -> tuple[str, ...]:
    """The finger's last jointed link and the fixed links below it, those with contact candidates."""
    jointed = {j.link for j in description.joints}
    last = max(i for i, link in enumerate(finger) if link in jointed)
    with_candidates = set(description.candidates_per_link())
    return tuple(link for link in finger[last:] if link in with_candidates)


def hand_fingers(hand) -> HandFingers | None:
    """The thumb and fingers of a described hand (module docstring); None without exactly one opposing finger, with
    no other finger, or when a tip group has no candidates."""
    description = hand.description
    if len(description.opposing) != 1:
        return None
    thumb = next(f for f in description.fingers if f[-1] == description.opposing[0])
    others = [f for f in description.fingers if f is not thumb]
    if not others:
        return None
    joints = torch.zeros(1, len(hand.joint_names), dtype=hand.dtype, device=hand.device)
    with torch.no_grad():
        frames = hand.forward_parts_torch(torch.eye(3, dtype=hand.dtype, device=hand.device)[None], joints.new_zeros(1, 3), joints)
    origin = frames.translation[0].double()
    thumb_base = origin[hand.link_index[thumb[0]]]
    base = lambda f: origin[hand.link_index[f[0]]]  # noqa: E731
    if len(others) > 2:  # the row's two end fingers; the index finger is the end nearer the thumb
        ends = max(((a, b) for a in others for b in others if a is not b), key=lambda ab: float((base(ab[0]) - base(ab[1])).norm()))
        first = min(ends, key=lambda f: float((base(f) - thumb_base).norm()))
    else:
        first = min(others, key=lambda f: float((base(f) - thumb_base).norm()))
    others.sort(key=lambda f: float((base(f) - base(first)).norm()))
    tips = [_tip_group(description, f) for f in (thumb, *others)]
    if not all(tips):
        return None
    finger_of_joint = [hand.link_index[j.link] for j in description.joints]
    joints_of = lambda f: tuple(j for j, link in enumerate(finger_of_joint) if hand.link_names[link] in f)  # noqa: E731
    flexion = tuple(0.0 if abs(abs(j.lower) - abs(j.upper)) < 1e-6 else (j.upper if abs(j.upper) > abs(j.lower) else j.lower)
                    for j in description.joints)
    return HandFingers(tips[0], tuple(tips[1:]), joints_of(thumb), tuple(joints_of(f) for f in others), flexion)


class _PregraspFit:
    """Gradient descent on one described hand's joints toward a type's pre-grasp (module docstring)."""

    def __init__(self, hand, fingers: HandFingers, finger_sides: tuple[int, ...]) -> None:
        self.hand = hand
        description = hand.description
        points = torch.as_tensor(np.asarray(description.contact_points), dtype=torch.float64)
        normals = torch.as_tensor(np.asarray(description.contact_normals), dtype=torch.float64)
        links = torch.as_tensor(np.asarray(description.contact_link), dtype=torch.long)

        def group(names):
            wanted = torch.tensor([hand.link_index[n] for n in names])
            rows = torch.isin(links, wanted).nonzero(as_tuple=True)[0]
            return points[rows], normals[rows], links[rows]

        self.thumb = group(fingers.thumb_tip)
        self.sides = [group(fingers.finger_tips[i]) for i in finger_sides]
        moving = set(fingers.thumb_joints) | {j for i in finger_sides for j in fingers.finger_joints[i]}
        self.moving = torch.tensor(sorted(moving))
        limits = hand.joint_limits.detach().double().cpu()
        self.lower, self.upper = limits[:, 0], limits[:, 1]
        flexion = torch.tensor(fingers.flexion_limit, dtype=torch.float64)
        rest = torch.as_tensor(np.asarray(description.pregrasp), dtype=torch.float64)
        self.start = rest.clone()
        curled = [j for i, joints in enumerate(fingers.finger_joints) if i not in finger_sides for j in joints]
        self.start[curled] = rest[curled] + CURL_FRACTION * (flexion[curled] - rest[curled])
        self.start[self.moving] = rest[self.moving] + FIT_START_FRACTION * (flexion[self.moving] - rest[self.moving])
        self.start = self.start.clamp(self.lower, self.upper)
        self.spen = SelfPenetrationTerm(hand)

    def measure(self, joints: torch.Tensor):
        """At ``joints`` (J,) float64: the opening between the two sides (m), the cosine between the thumb side's mean pad
        normal and the line to the finger side, that of each finger side's toward the thumb, and the link frames."""
        hand = self.hand
        frames = hand.forward_parts_torch(torch.eye(3, dtype=torch.float64)[None], torch.zeros(1, 3, dtype=torch.float64), joints[None])

        def side(group):
            p, n, link = group
            rot = frames.rotation[0, link]
            world_p = (rot @ p[..., None])[..., 0] + frames.translation[0, link]
            world_n = (rot @ n[..., None])[..., 0]
            mean_n = world_n.mean(0)
            return world_p.mean(0), mean_n / mean_n.norm().clamp(min=1e-9)

        thumb_p, thumb_n = side(self.thumb)
        finger = [side(g) for g in self.sides]
        finger_p = torch.stack([p for p, _ in finger]).mean(0)
        axis = finger_p - thumb_p
        opening = axis.norm()
        unit = axis / opening.clamp(min=1e-9)
        return opening, thumb_n @ unit, torch.stack([-(n @ unit) for _, n in finger]), frames

    def fit(self, opening_m: float, start: torch.Tensor) -> torch.Tensor:
        """(J,) float64 joints from ``start`` (the moving joints only change) at ``opening_m``, the sides facing."""
        moving = start[self.moving].clone().requires_grad_(True)
        optimizer = torch.optim.Adam([moving], lr=FIT_RATE)
        for _ in range(FIT_STEPS):
            joints = start.clone()
            joints[self.moving] = moving
            opening, thumb_cos, finger_cos, frames = self.measure(joints)
            loss = ((opening - opening_m) / OPENING_SCALE_M).square() + FACING_WEIGHT * ((1 - thumb_cos) + (1 - finger_cos).mean())
            loss = loss + SPEN_WEIGHT * self.spen.evaluate_with_torch(frames)[0] + STAY_WEIGHT * (moving - start[self.moving]).square().sum()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            with torch.no_grad():
                moving.copy_(torch.maximum(torch.minimum(moving, self.upper[self.moving]), self.lower[self.moving]))
        joints = start.clone()
        joints[self.moving] = moving.detach()
        return joints


Pairs = tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class DerivedType:
    """One precision type of a described hand, in ``optim.grasp_types.GraspType``'s terms: its four contact slots and two
    opposing sides (link names), and its aperture, closed and wide pre-grasp poses ((joint name, rad) pairs)."""

    name: str
    contact_slots: tuple[tuple[str, ...], ...]
    opposition: tuple[tuple[str, ...], tuple[str, ...]]
    aperture: Pairs
    closed: Pairs
    wide: Pairs


def _pairs(names: tuple[str, ...], joints: torch.Tensor) -> Pairs:
    return tuple((name, round(float(v), 4)) for name, v in zip(names, joints.tolist()))


def _fitted(hand, fingers: HandFingers, name: str, slots, finger_sides: tuple[int, ...]) -> DerivedType:
    fit = _PregraspFit(hand, fingers, finger_sides)
    aperture_m, closed_m, wide_m = OPENINGS_M[name]
    aperture = fit.fit(aperture_m, fit.start)
    closed, wide = fit.fit(closed_m, aperture), fit.fit(wide_m, aperture)
    names = tuple(hand.joint_names)
    opposition = (fingers.thumb_tip, tuple(link for i in finger_sides for link in fingers.finger_tips[i]))
    assert len(slots) == CONTACT_COUNT
    return DerivedType(name, slots, opposition, _pairs(names, aperture), _pairs(names, closed), _pairs(names, wide))


def _derive(hand) -> dict[str, DerivedType]:
    fingers = hand_fingers(hand)
    if fingers is None:
        return {}
    thumb, tips = fingers.thumb_tip, fingers.finger_tips
    types: dict[str, DerivedType] = {}
    if len(tips) >= 2:
        types["pinch"] = _fitted(hand, fingers, "pinch", (thumb, thumb, tips[0], tips[0] + tips[1]), (0,))
        types["tripod"] = _fitted(hand, fingers, "tripod", (thumb, thumb, tips[0], tips[1]), (0, 1))
    if len(tips) >= 3:
        types["rim"] = _fitted(hand, fingers, "rim", (thumb, thumb, tips[0] + tips[2], tips[1]), (0, 1, 2))
    return types


_FITTED: dict[str, dict[str, DerivedType]] = {}  # hand file -> its types, fitted once per process


def derived_types(hand) -> dict[str, DerivedType]:
    """Precision type name -> ``DerivedType`` of a described hand (module docstring; empty without a thumb and two more fingers),
    fitted once per hand file and process, in float64 on the CPU whatever the dtype and device of ``hand``."""
    description = hand.description
    key = f"{description.name}|{description.source}|{description.xml_string or ''}"
    if key not in _FITTED:
        _FITTED[key] = _derive(_float64_hand(hand))
    return _FITTED[key]


def _float64_hand(hand):
    """``hand`` when it is float64 on the CPU, else a float64 CPU hand of the same description (the fits' precision)."""
    if hand.dtype == torch.float64 and hand.device.type == "cpu":
        return hand
    from dexlite_pipeline.hand.described import DescribedHand

    return DescribedHand(hand.description, dtype=torch.float64)


def type_report_lines(hand) -> list[str]:
    """What ``dexlite hand-check`` says of a described hand's grasp types: each type's sides and, at its closed, aperture
    and wide pre-grasp, the opening (cm) and the largest angle between a side's mean pad normal and the line to the other
    side (degrees); why a hand has power grasps only."""
    types = derived_types(hand)
    if not types:
        return ["grasp types: power only (precision types need exactly one finger opposing the others and at least two more)"]
    fitting = _float64_hand(hand)
    fingers = hand_fingers(fitting)
    lines = [f"grasp types: power, {', '.join(types)} (thumb {'+'.join(fingers.thumb_tip)}; fingers from the index: "
             f"{', '.join('+'.join(tip) for tip in fingers.finger_tips)})"]
    for name, derived in types.items():
        sides = tuple(i for i, tip in enumerate(fingers.finger_tips) if set(tip) <= set(derived.opposition[1]))
        fit = _PregraspFit(fitting, fingers, sides)
        cells = []
        for label, pose in (("closed", derived.closed), ("aperture", derived.aperture), ("wide", derived.wide)):
            values = dict(pose)
            with torch.no_grad():
                opening, thumb_cos, finger_cos, _ = fit.measure(torch.tensor([values[n] for n in fitting.joint_names], dtype=torch.float64))
            worst = max([float(thumb_cos.clamp(-1, 1).arccos())] + [float(c) for c in finger_cos.clamp(-1, 1).arccos()])
            cells.append(f"{label} {100 * float(opening):.1f} cm, {np.degrees(worst):.0f} deg")
        lines.append(f"  {name}: contacts {' | '.join('+'.join(slot) for slot in derived.contact_slots)}; " + "; ".join(cells))
    return lines


__all__ = ["CURL_FRACTION", "OPENINGS_M", "DerivedType", "HandFingers", "derived_types", "hand_fingers", "type_report_lines"]
