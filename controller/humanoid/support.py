"""Which foot carries the robot, twice over: the gravity compensator's support state and the
LQR's contact, two notions the paper keeps apart.

`SupportState` (left, right, double): what the gravity compensator (5)-(7) splits the weight by
(mu = 0, 1, or from the CoM between the feet) and what the walking pattern's phases are.

`LqrContact` (left foot, right foot, both feet): the sole(s) whose 6-D contact Jc enters Sm of
(19) for the LQR. Kim et al., Sec. III-C: "the contact Jacobian Jc is the Jacobian of a
supporting foot, which is either left or right foot depending on the state of the robot. The
contact Jacobian is changed to the Jacobian of the other foot at the midpoint of the Double
Support Phase." `SmContactRule` names the two readings:

    "support-foot"  the paper's: one foot always; in a double support between single supports
                    on X and then Y, X for its first half and Y for its second (the switch at
                    the midpoint, tick start + n // 2); a double support with no single support
                    before it (the walk's start) uses the next stance foot's other foot for its
                    first half, one with none after it (the walk's end) the last stance foot's
                    other foot for its second half; a run that never leaves double support
                    (standing) uses the configured standing foot throughout
    "both-feet"     both soles in double support (the closed chain), one in single support

`lqr_contact_schedule` maps a run's per-tick support states to its per-tick LQR contacts.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence


class SupportState(enum.Enum):
    """Left single support, right single support, or double support."""

    LEFT = "left"
    RIGHT = "right"
    DOUBLE = "double"

    @property
    def feet(self) -> tuple[int, ...]:
        """Indices of the feet in contact (0 left, 1 right)."""
        if self is SupportState.DOUBLE:
            return (0, 1)
        return (0,) if self is SupportState.LEFT else (1,)


class LqrContact(enum.Enum):
    """The sole(s) held on the ground in the LQR's Sm of (19) (module docstring)."""

    LEFT_FOOT = "left-foot"
    RIGHT_FOOT = "right-foot"
    BOTH_FEET = "both-feet"

    @property
    def feet(self) -> tuple[int, ...]:
        """Indices of the soles in Jc (0 left, 1 right)."""
        return {
            LqrContact.LEFT_FOOT: (0,),
            LqrContact.RIGHT_FOOT: (1,),
            LqrContact.BOTH_FEET: (0, 1),
        }[self]

    @property
    def other_foot(self) -> LqrContact:
        if self is LqrContact.BOTH_FEET:
            raise ValueError("both feet have no other foot")
        return LqrContact.RIGHT_FOOT if self is LqrContact.LEFT_FOOT else LqrContact.LEFT_FOOT

    @staticmethod
    def of_single_support(support: SupportState) -> LqrContact:
        if support is SupportState.DOUBLE:
            raise ValueError("double support is not one foot")
        return LqrContact.LEFT_FOOT if support is SupportState.LEFT else LqrContact.RIGHT_FOOT


class SmContactRule(enum.Enum):
    """How the LQR's contact follows the support state (module docstring)."""

    SUPPORT_FOOT = "support-foot"
    BOTH_FEET = "both-feet"


def lqr_contact_schedule(
    supports: Sequence[SupportState],
    rule: SmContactRule,
    standing_foot: LqrContact = LqrContact.LEFT_FOOT,
) -> tuple[LqrContact, ...]:
    """The LQR's contact at every tick of a run whose support states are `supports` (one per
    tick), by `rule`; `standing_foot` for a run that never leaves double support (rule
    "support-foot")."""
    rule = SmContactRule(rule)
    if standing_foot is LqrContact.BOTH_FEET:
        raise ValueError("the standing foot is one foot")
    states = [SupportState(s) for s in supports]
    if rule is SmContactRule.BOTH_FEET:
        return tuple(
            LqrContact.BOTH_FEET if s is SupportState.DOUBLE else LqrContact.of_single_support(s)
            for s in states
        )
    contacts: list[LqrContact] = []
    tick = 0
    while tick < len(states):
        if states[tick] is not SupportState.DOUBLE:
            contacts.append(LqrContact.of_single_support(states[tick]))
            tick += 1
            continue
        end = tick
        while end < len(states) and states[end] is SupportState.DOUBLE:
            end += 1
        before = contacts[-1] if contacts else None
        after = LqrContact.of_single_support(states[end]) if end < len(states) else None
        if before is None and after is None:
            first = second = standing_foot
        else:
            first = before if before is not None else after.other_foot  # type: ignore[union-attr]
            second = after if after is not None else first.other_foot
        middle = tick + (end - tick) // 2
        contacts.extend([first] * (middle - tick) + [second] * (end - middle))
        tick = end
    return tuple(contacts)
