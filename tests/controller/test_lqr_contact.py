"""The LQR's contact (controller/humanoid/support.py): the paper's support foot switched at the
midpoint of each double support (Kim et al., Sec. III-C), against ticks counted by hand on a
walk's timeline; both feet in double support as the other reading."""

from __future__ import annotations

import pytest

from controller.humanoid import LqrContact, SmContactRule, SupportState, lqr_contact_schedule

D, L, R = SupportState.DOUBLE, SupportState.LEFT, SupportState.RIGHT
LF, RF, BF = LqrContact.LEFT_FOOT, LqrContact.RIGHT_FOOT, LqrContact.BOTH_FEET


def _walk(rest: int, ds: int, ss: int, stances: list[SupportState]) -> list[SupportState]:
    """rest, then (double support, single support on each stance), a last double support and
    a rest: the timeline's shape (controller/walking/timeline.py)."""
    ticks = [D] * rest
    for stance in stances:
        ticks += [D] * ds + [stance] * ss
    return ticks + [D] * ds + [D] * rest


def test_the_support_foot_switches_at_the_middle_of_each_double_support() -> None:
    # the paper's dynamic timing on the 200 Hz grid: 0.3 s double (60 ticks), 0.8 s single
    ds, ss = round(0.3 / 0.005), round(0.8 / 0.005)
    supports = _walk(0, ds, ss, [L, R, L])
    contacts = lqr_contact_schedule(supports, SmContactRule.SUPPORT_FOOT)
    # the double support between L (ticks 60..219) and R starts at 220: L until 220 + 30
    start = ds + ss
    assert contacts[start - 1] is LF
    assert all(c is LF for c in contacts[start : start + ds // 2])
    assert all(c is RF for c in contacts[start + ds // 2 : start + ds + ss])
    # the first double support: the first stance foot's other foot, then the stance foot
    assert contacts[: ds // 2] == (RF,) * (ds // 2)
    assert contacts[ds // 2 : ds] == (LF,) * (ds - ds // 2)
    # the last: the last stance foot, then its other foot (the foot that landed)
    end = len(supports)
    last_ds = end - ds
    assert contacts[last_ds : last_ds + ds // 2] == (LF,) * (ds // 2)
    assert contacts[last_ds + ds // 2 :] == (RF,) * (ds - ds // 2)
    # never both feet, and a single support is always its own foot
    assert BF not in contacts
    for support, contact in zip(supports, contacts, strict=True):
        if support is not D:
            assert contact is LqrContact.of_single_support(support)


def test_an_odd_double_support_switches_at_its_integer_middle() -> None:
    contacts = lqr_contact_schedule([L] * 2 + [D] * 5 + [R] * 2, SmContactRule.SUPPORT_FOOT)
    assert contacts == (LF, LF, LF, LF, RF, RF, RF, RF, RF)  # start 2 + 5 // 2 = tick 4


def test_standing_uses_the_standing_foot_and_both_feet_the_closed_chain() -> None:
    stand = [D] * 7
    assert lqr_contact_schedule(stand, SmContactRule.SUPPORT_FOOT) == (LF,) * 7
    assert lqr_contact_schedule(stand, SmContactRule.SUPPORT_FOOT, RF) == (RF,) * 7
    walk = [D, D, L, L, D, R]
    assert lqr_contact_schedule(walk, SmContactRule.BOTH_FEET) == (BF, BF, LF, LF, BF, RF)
    with pytest.raises(ValueError):
        lqr_contact_schedule(stand, SmContactRule.SUPPORT_FOOT, BF)
