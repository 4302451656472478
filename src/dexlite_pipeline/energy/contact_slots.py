"""Which contact candidates each of a grasp's four contacts may be drawn from (a grasp type's contact template).

A grasp's four contacts are indices into the hand's contact table (``ShadowHand.all_contact_points_local``: the 140
palmar pads, then the side candidates, then the thumb-tip candidates). Without slots every contact may be any pad (DexGraspNet's power grasps). A
contact template restricts contact k to its own set of candidates, e.g. two contacts on the thumb tip and two on the
index fingertip for a pinch, so that the random draws of the optimizer and the contact search
(``GraspEnergy.best_contacts``) only ever choose contacts the grasp type allows. Slots are kept per grasp type (a
table of T templates) and per grasp (its template's row), so one batch may mix grasp types.
"""

from __future__ import annotations

import torch

CONTACT_COUNT = 4  # contacts of a grasp: the four points E_fc and E_dis are computed at


class ContactSlots:
    """Per grasp, the candidates each of its ``CONTACT_COUNT`` contacts may take.

    ``table`` (T, 4, K) candidate indices of each template's slots, padded with the slot's first candidate;
    ``counts`` (T, 4) how many of the K are the slot's; ``kind`` (B,) each grasp's template (row of ``table``).
    """

    def __init__(self, table: torch.Tensor, counts: torch.Tensor, kind: torch.Tensor) -> None:
        if table.ndim != 3 or table.shape[1] != CONTACT_COUNT or counts.shape != table.shape[:2]:
            raise ValueError(f"contact slots: table (T, {CONTACT_COUNT}, K) and counts (T, {CONTACT_COUNT}) expected, "
                             f"got {tuple(table.shape)} and {tuple(counts.shape)}")
        if bool((counts < 1).any()):
            raise ValueError("contact slots: every slot needs at least one candidate")
        self.table, self.counts, self.kind = table.long(), counts.long(), kind.long()

    @classmethod
    def from_templates(cls, templates: list[tuple[tuple[int, ...], ...]], kind: torch.Tensor) -> "ContactSlots":
        """Slots from one template per kind: ``CONTACT_COUNT`` tuples of candidate indices each."""
        width = max(len(slot) for template in templates for slot in template)
        table = torch.zeros(len(templates), CONTACT_COUNT, width, dtype=torch.long)
        counts = torch.zeros(len(templates), CONTACT_COUNT, dtype=torch.long)
        for t, template in enumerate(templates):
            if len(template) != CONTACT_COUNT:
                raise ValueError(f"contact template {t}: {len(template)} slots, expected {CONTACT_COUNT}")
            for k, slot in enumerate(template):
                table[t, k] = torch.tensor(list(slot) + [slot[0]] * (width - len(slot)))
                counts[t, k] = len(slot)
        return cls(table, counts, kind.cpu())

    def __len__(self) -> int:
        return len(self.kind)

    @property
    def candidate_count(self) -> int:
        """One more than the largest candidate index any slot holds: how much of the contact table the slots need."""
        return int(self.table.max()) + 1

    def take(self, rows: torch.Tensor) -> "ContactSlots":
        """The slots of the grasps at ``rows`` only."""
        return ContactSlots(self.table, self.counts, self.kind[rows.cpu()])

    def draw(self, uniform: torch.Tensor) -> torch.Tensor:
        """(B, 4) candidate indices from uniforms (B, 4) in [0, 1): contact k takes entry ⌊u·count⌋ of its slot."""
        counts = self.counts[self.kind]  # (B, 4)
        position = (uniform.double() * counts).long().clamp(max=counts - 1)
        return torch.gather(self.table[self.kind], 2, position[..., None])[..., 0]

    def masks(self, candidate_count: int) -> torch.Tensor:
        """(B, 4, N) bool: whether candidate n may carry contact k (N = ``candidate_count`` entries of the contact table)."""
        allowed = torch.zeros(len(self.table), CONTACT_COUNT, candidate_count, dtype=torch.bool)
        for t in range(len(self.table)):
            for k in range(CONTACT_COUNT):
                allowed[t, k, self.table[t, k, : int(self.counts[t, k])]] = True
        return allowed[self.kind]
