"""Grasp types of optimization from scratch: one contact template, pre-grasp pose and start rule per type.

Optimization from scratch with DexGraspNet's energies finds power grasps: the palm facing the object, four contacts
anywhere on the 140 palmar pads. Objects that need the fingertips (a bowl's rim, a hammer or spatula lying on the
table, a plate) get almost none. The grasp taxonomy (Feix et al., "The GRASP taxonomy of human grasp types", 2016)
names the other ways a hand holds things, and Dexonomy (RSS 2025) synthesizes each type for a robot hand from one
contact template per hand and type. Here a type is data (``GraspType``):

- ``contact_slots``: for each of the four force-closure contacts, the candidate groups it may be drawn from
  (``candidate_group``: a link's palmar pads, its side candidates, or the thumb's tip candidates), enforced in
  every draw and contact search of the optimizer (``energy.contact_slots``); the energies themselves are unchanged,
  so the other links are kept out of the object and the table by E_pen and E_table as for power grasps.
- ``aperture``: the mean pre-grasp joint angles the fingers start from (noise as for power starts): for precision
  types the participating pads face each other a few centimetres apart and the other fingers are curled away.
- ``closed`` and ``wide``: the pre-grasp pose with the opposing pads nearly closed and opened wide; a start blends
  between them and the aperture to fit the object's thickness where it closes (``pregrasp_joints``).
- the start: for power the convex-hull start of ``optim.init`` (section ``optimize_grasps.init``); for the others
  ``optim.type_starts``: preferably on a pair of opposing surface points across the object that fits the opening
  (a bowl's wall, a handle, a box's narrow side), the grasp centre at the pair's midpoint and the hand opened to its
  thickness plus a gap, so the pads start on either side of it; without such a pair, the grasp centre between the
  opposing pads is placed ``centre_distance_m`` outside a target point, approached either from the side (a
  convex-hull point, along its inward normal) or from above (palm facing down, at a point of the object's rim: where
  its upward-facing top ends), the opening across the rim. An object lower on its table than ``low_object_height_m``
  is approached from above only; a taller one with share ``above_share``.

The aperture joint values were fitted (then rounded) so that the opposing pads of each precision type face each other
at the opening named in each type's comment (each side's mean pad normal within 15° of the line between the two
sides), the other fingers curled, the hand clear of itself; the closed and wide poses were fitted the same way
(gradient descent on the named joints from the aperture: the opening to about 2 and 10 cm, 1.7 and 6.7 cm for
lateral, each pad normal within about 20° of the line, no self-penetration; the wide pinch's middle finger then set
to the index finger's flexion, so that it stays beside it), so every blend between them opens steadily with the pads
facing; ``tests/optim/test_grasp_types.py`` checks those properties.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import torch

from dexlite_pipeline.energy.contact_slots import CONTACT_COUNT, ContactSlots
from dexlite_pipeline.hand.model import JOINT_NAMES, PAD as PAD_KIND, SIDE as SIDE_KIND, TIP as TIP_KIND, ShadowHand
from dexlite_pipeline.model.type_condition import interleaved_plan
from dexlite_pipeline.optim.init import MEAN_OPEN_POSE

# A finger folded away from a precision grasp: proximal, middle and distal flexion (rad).
CURLED = (("J2", 1.2), ("J1", 1.2), ("J0", 0.8))
# Suffix of a candidate group naming a link's side candidates (``ShadowHand.side_contact_points_local``).
SIDE = ":side"
# Suffix of a candidate group naming a link's tip candidates (``ShadowHand.tip_contact_points_local``: the thumb's).
TIP = ":tip"
# The thumb's contact in a pinch or tripod: its palmar pads or its tip (on a thin wall or a handle lying on the table the
# thumb touches with the tip, beyond its pads: docs/results_journal.md, 2026-12-05).
THUMB_PAD_OR_TIP = ("thdistal", "thdistal" + TIP)


# The joints a Shadow Hand type names, in joint order (without ``robot0:``); a described hand's types name its own.
SHADOW_JOINTS = tuple(name.removeprefix("robot0:") for name in JOINT_NAMES)


def _curled(*fingers: str) -> tuple[tuple[str, float], ...]:
    return tuple((f"{finger}{joint}", angle) for finger in fingers for joint, angle in CURLED)


@dataclass(frozen=True)
class GraspType:
    """One grasp type: its contact template, pre-grasp pose and start rule (module docstring).

    ``contact_slots``: four tuples of candidate groups (``candidate_group``), one per contact; None: every contact
    may be any palmar pad (power). ``aperture``: (joint name without ``robot0:``, radians) pairs of the mean
    pre-grasp pose, other joints 0. ``opposition``: the candidate groups of the two sides that close on the object
    (thumb side, finger side); the grasp centre is midway between their mean positions in the aperture pose and the
    opening axis runs from the first to the second. None: the power start (``optim.init``). ``centre_distance_m``:
    range of the grasp centre's start distance outside the target point (m). ``above_share``: share of the starts
    from above on objects at least ``low_object_height_m`` tall on their table (m); lower ones are approached from
    above only. ``jitter_deg``: the approach's tilt off the nominal direction, at most this (degrees).
    ``closed`` and ``wide``: the joints (same form; the others as in ``aperture``) of the pre-grasp pose with the
    opposing pads nearly closed and opened as wide as they still face each other; a start on a pair of opposing
    surface points opens the hand between them to fit the object there (``pregrasp_joints``). Empty: the aperture only.
    ``joint_names``: the hand's joints in order, as the poses name them (the Shadow Hand's without ``robot0:``; a hand
    from its MJCF: ``optim.described_types``).
    """

    name: str
    contact_slots: tuple[tuple[str, ...], ...] | None
    aperture: tuple[tuple[str, float], ...]
    opposition: tuple[tuple[str, ...], tuple[str, ...]] | None = None
    centre_distance_m: tuple[float, float] = (0.0, 0.0)
    above_share: float = 0.0
    low_object_height_m: float = 0.0
    jitter_deg: float = 0.0
    closed: tuple[tuple[str, float], ...] = ()
    wide: tuple[tuple[str, float], ...] = ()
    joint_names: tuple[str, ...] = SHADOW_JOINTS

    def __post_init__(self) -> None:
        if self.contact_slots is not None and len(self.contact_slots) != CONTACT_COUNT:
            raise ValueError(f"grasp type {self.name}: {len(self.contact_slots)} contact slots, expected {CONTACT_COUNT}")
        unknown = sorted({joint for joint, _ in (*self.aperture, *self.closed, *self.wide)} - set(self.joint_names))
        if unknown:
            raise ValueError(f"grasp type {self.name}: unknown aperture joints {', '.join(unknown)}")
        if bool(self.closed) != bool(self.wide):
            raise ValueError(f"grasp type {self.name}: give both the closed and the wide pre-grasp pose, or neither")

    def aperture_joints(self) -> torch.Tensor:
        """(J,) float64 the aperture in joint order (the Shadow Hand's 22)."""
        values = dict(self.aperture)
        return torch.tensor([values.get(name, 0.0) for name in self.joint_names], dtype=torch.float64)

    def pregrasp_joints(self, blend: float) -> torch.Tensor:
        """(J,) float64 pre-grasp joints along the opening: ``blend`` 0 the closed pose, 1 the aperture, 2 the wide pose,
        linear in joint space between them (the aperture for every blend when the type has no closed and wide pose)."""
        aperture = self.aperture_joints()
        if not self.closed or blend == 1.0:
            return aperture
        other = dict(self.aperture) | dict(self.closed if blend < 1.0 else self.wide)
        end = torch.tensor([other.get(name, 0.0) for name in self.joint_names], dtype=torch.float64)
        weight = min(abs(blend - 1.0), 1.0)
        return (1.0 - weight) * aperture + weight * end


POWER = GraspType("power", contact_slots=None, aperture=tuple(MEAN_OPEN_POSE.items()))

# Precision pinch (taxonomy: palmar pinch / tip pinch): thumb tip against index fingertip, the middle fingertip
# optionally a fourth contact beside the index; ring and little fingers curled. Pads ~7 cm apart.
PINCH = GraspType(
    "pinch",
    contact_slots=(THUMB_PAD_OR_TIP, THUMB_PAD_OR_TIP, ("ffdistal",), ("ffdistal", "mfdistal")),
    aperture=(("FFJ2", 0.2), ("FFJ1", 0.5), ("FFJ0", 0.45), ("MFJ2", 0.2), ("MFJ1", 0.5), ("MFJ0", 0.45),
              ("THJ4", 0.85), ("THJ3", 0.95), ("THJ2", -0.15), ("THJ1", 0.5), *_curled("RF", "LF")),
    opposition=(("thdistal",), ("ffdistal",)),
    centre_distance_m=(0.005, 0.03), above_share=0.5, low_object_height_m=0.06, jitter_deg=20.0,
    # pads ~2 cm and ~10 cm apart
    closed=(("FFJ3", -0.35), ("FFJ2", 1.0), ("FFJ1", 0.82), ("FFJ0", 0.03), ("MFJ2", 0.2), ("MFJ1", 0.5), ("MFJ0", 0.45),
            ("THJ4", 0.59), ("THJ3", 1.04), ("THJ2", -0.02), ("THJ1", 0.33)),
    wide=(("FFJ3", -0.21), ("FFJ2", 0.0), ("FFJ1", 0.36), ("FFJ0", 0.54), ("MFJ3", -0.18), ("MFJ2", 0.0), ("MFJ1", 0.36), ("MFJ0", 0.54),
          ("THJ4", 0.47), ("THJ3", 0.92), ("THJ2", -0.07), ("THJ1", 0.28)),
)

# Tripod (taxonomy: tripod / prismatic 3-finger): thumb tip against the index and middle fingertips; ring and
# little fingers curled. Thumb pad ~6 cm from the middle of the two finger pads.
TRIPOD = GraspType(
    "tripod",
    contact_slots=(THUMB_PAD_OR_TIP, THUMB_PAD_OR_TIP, ("ffdistal",), ("mfdistal",)),
    aperture=(("FFJ3", -0.25), ("FFJ2", 0.55), ("FFJ1", 0.5), ("FFJ0", 0.3), ("MFJ3", -0.25), ("MFJ2", 0.55), ("MFJ1", 0.5),
              ("MFJ0", 0.3), ("THJ4", 0.8), ("THJ3", 1.1), ("THJ2", -0.05), ("THJ1", 0.5), *_curled("RF", "LF")),
    opposition=(("thdistal",), ("ffdistal", "mfdistal")),
    centre_distance_m=(0.005, 0.03), above_share=0.5, low_object_height_m=0.06, jitter_deg=20.0,
    # pads ~2.5 cm and ~10 cm apart
    closed=(("FFJ3", -0.35), ("FFJ2", 1.26), ("FFJ1", 0.59), ("FFJ0", 0.0), ("MFJ3", -0.26), ("MFJ2", 0.95), ("MFJ1", 0.75), ("MFJ0", 0.08),
            ("THJ4", 0.66), ("THJ3", 1.14), ("THJ2", -0.02), ("THJ1", 0.37)),
    wide=(("FFJ3", -0.3), ("FFJ2", 0.35), ("FFJ1", 0.41), ("FFJ0", 0.33), ("MFJ3", -0.35), ("MFJ2", 0.3), ("MFJ1", 0.41), ("MFJ0", 0.33),
          ("THJ4", 0.35), ("THJ3", 1.09), ("THJ2", -0.03), ("THJ1", 0.25), ("THJ0", -0.03)),
)

# Lateral (taxonomy: lateral / key pinch): the thumb pad presses the object against the radial side of the index
# finger's middle phalanx; the index is flexed, the other fingers curled. Pads ~4 cm apart. The thumb keeps its pads
# only: with its tip candidates too, more lateral grasps met the energy thresholds but fewer held (bowl and spatula 037,
# 32 starts: held 12 -> 7, within thresholds and held 5 -> 5; docs/results_journal.md, 2026-12-05).
LATERAL = GraspType(
    "lateral",
    contact_slots=(("thdistal",), ("thdistal",), ("ffmiddle" + SIDE,), ("ffmiddle" + SIDE,)),
    aperture=(("FFJ3", 0.3), ("FFJ2", 1.2), ("FFJ1", 1.0), ("FFJ0", 0.3), ("THJ4", -0.2), ("THJ3", 0.5), ("THJ0", -0.4),
              *_curled("MF", "RF", "LF")),
    opposition=(("thdistal",), ("ffmiddle" + SIDE,)),
    centre_distance_m=(0.005, 0.025), above_share=0.5, low_object_height_m=0.06, jitter_deg=20.0,
    # pads ~1.7 cm and ~6.7 cm apart
    closed=(("FFJ3", 0.35), ("FFJ2", 1.22), ("FFJ1", 0.85), ("FFJ0", 0.3), ("THJ4", 0.22), ("THJ3", 0.69), ("THJ2", 0.01), ("THJ1", -0.14),
            ("THJ0", -0.21)),
    wide=(("FFJ3", 0.16), ("FFJ2", 1.01), ("FFJ1", 0.85), ("FFJ0", 0.3), ("THJ4", -0.48), ("THJ3", 0.41), ("THJ2", -0.01), ("THJ1", 0.25),
          ("THJ0", -0.34)),
)

# Rim: the thumb on one side of a rim or edge, the index, middle and ring fingertips on the other, index and ring ~3.5 cm
# apart along the rim and level, the middle ~2 cm deeper, the thumb opposite their centroid; little finger curled.
# Why: on a wall every contact normal is nearly across it, so the torques in the wall's plane (the object tipping about
# the rim's tangent under its weight, turning about the line across the wall) come from the normal forces only when the
# thumb-side contact lies inside the polygon of the finger-side contacts; otherwise one of them is held by friction across
# the wall's thickness alone. A pinch (contacts on one line across the wall) and any tripod (two fingertips: a segment)
# are of that kind: curation's Ferrari-Canny epsilon (friction 0.6, torques over a 0.14 m scale) of ideal contacts on a
# 4 mm wall is 0 for a pinch, 0.006 for a tripod spread 3 cm along or down the rim, 0.019-0.022 for the thumb inside a
# triangle of three fingertips 3-4 cm wide and 2 cm deep (curation keeps above 0.01). The template has two thumb slots and
# two finger slots (the middle, and the index or the ring): E_fc sums the slot contacts' unit normals, so one thumb slot
# against three fingertips can never balance (|sum n| ~ 2, E_fc ~ 4: 1% of such grasps met the energy thresholds on pots,
# pans, plates and bowls); the third fingertip is brought to the wall by the start pose, not by the energy. Started from
# above only (``above_share`` 1): palm down, the opening across the wall, the index-to-ring line (⟂ approach and opening
# in the hand) lies along the rim and the middle finger reaches down the wall (measured: results journal, "A rim grasp
# with contacts spread along the rim (#47)", 2026-12-05).
# Pads ~6 cm apart (fitted like the others, with the index-to-ring distance along the hand's third axis (the two level),
# the middle's depth along the approach and the thumb at the three pads' centroid as further targets, the blends towards
# the aperture kept clear of self-penetration).
RIM = GraspType(
    "rim",
    contact_slots=(THUMB_PAD_OR_TIP, THUMB_PAD_OR_TIP, ("ffdistal", "rfdistal"), ("mfdistal",)),
    aperture=(("FFJ3", -0.35), ("FFJ1", 1.08), ("MFJ3", -0.35), ("MFJ2", 1.14), ("MFJ1", 0.29), ("RFJ3", -0.12), ("RFJ2", 0.34),
              ("RFJ1", 0.94), ("RFJ0", 0.01), ("THJ4", 0.83), ("THJ3", 1.22), ("THJ1", 0.52), *_curled("LF")),
    opposition=(("thdistal",), ("ffdistal", "mfdistal", "rfdistal")),
    centre_distance_m=(0.005, 0.03), above_share=1.0, low_object_height_m=0.06, jitter_deg=20.0,
    # pads ~2.4 cm and ~10 cm apart; index to ring ~4.4 and ~3.5 cm, the middle 0.8 and 2 cm deeper
    closed=(("FFJ3", -0.35), ("FFJ2", 0.76), ("FFJ1", 1.11), ("FFJ0", 0.0), ("MFJ3", -0.35), ("MFJ2", 1.57), ("MFJ1", 0.0), ("MFJ0", 0.0),
            ("RFJ3", -0.35), ("RFJ2", 1.55), ("RFJ1", 0.0), ("RFJ0", 0.0), ("THJ4", 0.76), ("THJ3", 1.22), ("THJ2", 0.1), ("THJ1", 0.52),
            ("THJ0", 0.0)),
    wide=(("FFJ3", -0.35), ("FFJ2", 0.0), ("FFJ1", 0.0), ("FFJ0", 0.88), ("MFJ3", -0.35), ("MFJ2", 0.57), ("MFJ1", 0.14), ("MFJ0", 0.22),
          ("RFJ3", -0.18), ("RFJ2", 0.25), ("RFJ1", 0.0), ("RFJ0", 1.03), ("THJ4", 0.34), ("THJ3", 1.07), ("THJ2", 0.21), ("THJ1", -0.09),
          ("THJ0", 0.0)),
)

# Every grasp type by name, in the order starts are assigned and drawn (``assign_types``); index = ``type code`` (a new type
# goes last, so the codes of stored grasps and the draws of the other types stay as they were).
GRASP_TYPES: dict[str, GraspType] = {t.name: t for t in (POWER, PINCH, TRIPOD, LATERAL, RIM)}
TYPE_NAMES: tuple[str, ...] = tuple(GRASP_TYPES)
POWER_CODE = TYPE_NAMES.index("power")


def hand_grasp_types(hand: ShadowHand) -> dict[str, GraspType]:
    """The grasp types ``hand`` offers, by name: every one of ``GRASP_TYPES`` for the Shadow Hand; for a hand from its
    MJCF those its description allows (``optim.described_types``: power, and pinch, tripod and rim by its fingers)."""
    from dexlite_pipeline.hand.described import is_described

    if not is_described(hand):
        return GRASP_TYPES
    from dexlite_pipeline.optim.described_types import derived_types

    names = tuple(hand.joint_names)
    types = {"power": GraspType("power", contact_slots=None, aperture=tuple(zip(names, map(float, hand.description.pregrasp))), joint_names=names)}
    for name, derived in derived_types(hand).items():
        shadow = GRASP_TYPES[name]  # the start rule's distances and shares: about the object and the table, not the hand
        types[name] = GraspType(name, contact_slots=derived.contact_slots, aperture=derived.aperture, opposition=derived.opposition,
                                centre_distance_m=shadow.centre_distance_m, above_share=shadow.above_share,
                                low_object_height_m=shadow.low_object_height_m, jitter_deg=shadow.jitter_deg, closed=derived.closed,
                                wide=derived.wide, joint_names=names)
    return types


def check_hand_offers(hand: ShadowHand, type_names) -> None:
    """ValueError in one line naming the first of ``type_names`` that ``hand`` does not offer (``hand_grasp_types``)."""
    offered = hand_grasp_types(hand)
    for name in dict.fromkeys(str(t) for t in type_names):
        if name not in offered:
            hand_name = getattr(getattr(hand, "description", None), "name", "shadow")
            raise ValueError(f"hand {hand_name}: grasp type {name} is not defined for this hand (it offers {', '.join(offered)})")


def candidate_group(hand: ShadowHand, group: str) -> tuple[int, ...]:
    """Contact-table indices of a candidate group: ``"<link>"`` its palmar pads, ``"<link>:side"`` its side candidates,
    ``"<link>:tip"`` its tip candidates (the Shadow Hand's link names without ``robot0:``, a hand from its MJCF's as
    they are)."""
    from dexlite_pipeline.hand.described import is_described

    link, kind = group, PAD_KIND
    for suffix, suffix_kind in ((SIDE, SIDE_KIND), (TIP, TIP_KIND)):
        if group.endswith(suffix):
            link, kind = group.removesuffix(suffix), suffix_kind
    name = link if is_described(hand) else f"robot0:{link}"
    if name not in hand.link_index:
        raise ValueError(f"candidate group {group!r}: no hand link {name}")
    found = hand.candidates_on((name,), kind)
    if not found:
        raise ValueError(f"candidate group {group!r}: the hand has no {kind} candidates on {name}")
    return found


def contact_template(hand: ShadowHand, grasp_type: GraspType) -> tuple[tuple[int, ...], ...]:
    """The four slots of ``grasp_type`` as contact-table indices (power: every pad in each slot; for a hand from its MJCF
    with a thumb, the first on the thumb, as ``power_slots``)."""
    if grasp_type.contact_slots is None:
        every = tuple(range(hand.pad_candidate_count))
        opposing = _opposing_candidates(hand)
        return (opposing or every,) + (every,) * (CONTACT_COUNT - 1)
    return tuple(tuple(sorted({i for group in slot for i in candidate_group(hand, group)})) for slot in grasp_type.contact_slots)


def contact_slots(hand: ShadowHand, type_codes: torch.Tensor) -> ContactSlots:
    """The ``ContactSlots`` of grasps of the given types (``TYPE_NAMES`` indices, (B,)); ValueError for a type the hand
    does not offer (``check_hand_offers``)."""
    offered = hand_grasp_types(hand)
    check_hand_offers(hand, [TYPE_NAMES[int(code)] for code in torch.unique(type_codes).tolist()])
    # A type the hand lacks takes the power template: no grasp has its code (checked above), the table needs every row.
    templates = [contact_template(hand, offered.get(name, offered["power"])) for name in TYPE_NAMES]
    return ContactSlots.from_templates(templates, type_codes)


def power_slots(hand: ShadowHand, count: int) -> ContactSlots | None:
    """The ``ContactSlots`` of ``count`` power grasps of ``hand``: None (any pad in every slot) for the Shadow Hand and for
    a hand whose fingers all face one way; for a hand from its MJCF with an opposing finger (a thumb:
    ``HandDescription.opposing``), the first contact on that finger's candidates and the other three on any pad.

    Why: force closure needs contacts whose normals oppose, and the contact draws and searches prefer candidates already
    near the surface; a hand that reaches the object with its fingers first then keeps four finger-side contacts, whose
    normals cannot balance (E_fc stays high), and nothing pulls the thumb in. With one contact on the thumb, E_dis pulls
    the thumb onto the object opposite the fingers (measured: docs/results_journal.md, "LEAP's thumb contact")."""
    opposing = _opposing_candidates(hand)
    if not opposing:
        return None
    every = tuple(range(hand.pad_candidate_count))
    return ContactSlots.from_templates([(opposing, every, every, every)], torch.zeros(count, dtype=torch.long))


def _opposing_candidates(hand: ShadowHand) -> tuple[int, ...]:
    """The thumb's candidates of a hand from its MJCF (``DescribedHand.opposing_candidates``); empty for the Shadow Hand."""
    from dexlite_pipeline.hand.described import is_described

    return hand.opposing_candidates() if is_described(hand) else ()


def slots_of_types(hand: ShadowHand, type_names) -> ContactSlots | None:
    """The ``ContactSlots`` of grasps of the named types (e.g. a store's ``grasp_type``); when every one is power, those
    of ``power_slots`` (None for the Shadow Hand: any pad, the same draws as before grasp types). ValueError naming an
    unknown type."""
    names = [str(t) for t in type_names]
    unknown = sorted(set(names) - set(TYPE_NAMES))
    if unknown:
        raise ValueError(f"unknown grasp type(s) {', '.join(unknown)} (known: {', '.join(TYPE_NAMES)})")
    if all(name == "power" for name in names):
        return power_slots(hand, len(names))
    return contact_slots(hand, torch.as_tensor([TYPE_NAMES.index(name) for name in names], dtype=torch.long))


def normalized_shares(shares: Mapping[str, float]) -> dict[str, float]:
    """``shares`` (type name -> weight ≥ 0) divided by their sum, in ``TYPE_NAMES`` order, zero shares left out.

    ValueError for an unknown name, a negative or non-finite weight, or no positive one."""
    unknown = sorted(set(shares) - set(TYPE_NAMES))
    if unknown:
        raise ValueError(f"unknown grasp type(s) {', '.join(unknown)} (known: {', '.join(TYPE_NAMES)})")
    bad = sorted(name for name, share in shares.items() if not (math.isfinite(share) and share >= 0))
    if bad:
        raise ValueError(f"grasp type share(s) of {', '.join(bad)} must be finite and at least 0")
    total = sum(shares.values())
    if total <= 0:
        raise ValueError("every grasp type share is 0: give at least one type a positive share")
    return {name: shares[name] / total for name in TYPE_NAMES if shares.get(name, 0) > 0}


def assign_types(shares: Mapping[str, float], count: int) -> np.ndarray:
    """(count,) type codes (``TYPE_NAMES`` indices) of ``count`` consecutive starts in the proportions of ``shares``.

    Start j takes the type furthest behind its share of the first j + 1 starts (ties: the earlier type), so the
    types are interleaved, every prefix holds each type within one start of its share, and the whole block within
    one of count · share. The same for every seed and object: a mix is a fixed plan, not a draw.
    """
    weights = normalized_shares(shares)
    codes = np.array([TYPE_NAMES.index(name) for name in weights], dtype=np.int64)
    return codes[interleaved_plan(np.array(list(weights.values())), count)]
