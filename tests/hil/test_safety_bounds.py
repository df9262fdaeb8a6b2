"""Every [safety] figure at its bound (accepted) and just past it (refused, naming the key).

The bounds are written here, from what each figure means, not read from the schema: a range
loosened in hil/config/schema.py (say `current_guard_fraction` allowed above 1, which would
keep the software overload guard from ever firing) fails this test. A [safety] key without a
row here fails it too."""

from __future__ import annotations

import math

import pytest

from hil.config import ConfigError, SafetySection, load_config

TINY = 1e-9
# key: (the value at its bound, accepted; the value just past it, refused)
BOUNDS: dict[str, tuple[float, float]] = {
    "max_goal_rate_rad_s": (TINY, 0.0),  # > 0: a goal must be able to move
    "max_deflection_rad": (0.01, 0.0),  # > 0 (and >= zero_offset_margin_rad, below)
    "zero_offset_margin_rad": (TINY, 0.0),  # > 0
    "current_guard_fraction": (1.0, 1.0 + TINY),  # of the current limit: at most all of it
    "current_guard_fraction ": (TINY, 0.0),  # (its lower bound) > 0
    "current_guard_time_s": (TINY, 0.0),  # > 0
    "current_guard_backoff_rad": (0.0, -TINY),  # >= 0
    "current_guard_margin_s": (1.5 - TINY, 1.5),  # below the H54's modelled overload trip time
    "current_guard_margin_s ": (TINY, 0.0),  # (its lower bound) > 0
    "link_stale_ticks": (1, 0),  # >= 1 tick
    "bus_error_ticks": (1, 0),  # >= 1 tick
    "overrun_limit": (0, -1),  # >= 0 missed deadlines
    "link_noise_jump_rad": (TINY, 0.0),  # > 0
    "link_noise_window_ticks": (2, 1),  # a second difference needs two ticks to alternate
    "link_noise_fraction": (1.0, 1.0 + TINY),  # a share of the window: at most all of it
    "link_noise_fraction ": (TINY, 0.0),  # (its lower bound) > 0
    "overrun_window_s": (0.15, 0.0),  # > 0 (and holding more ticks than overrun_limit)
    "max_kdist": (0.0, -TINY),  # >= 0: Kdist itself is >= 0
    "goal_saturation_fraction": (1.0, 1.0 + TINY),  # a share: at most all
    "goal_saturation_fraction ": (TINY, 0.0),  # (its lower bound) > 0
    "goal_saturation_window_ticks": (1, 0),  # >= 1 tick
}
NOT_NUMBERS = {"current_guard"}  # a switch; the on_* keys are reactions (tested below)


def _set(key: str, value: float):
    """The built-in configuration with one [safety] key changed (an error names the key where
    the validation found it, as for a file)."""
    return load_config().changed("safety", **{key.strip(): value})


def test_every_safety_figure_has_its_bounds_here() -> None:
    numbers = {
        name
        for name, field in SafetySection.model_fields.items()
        if not name.startswith("on_") and name not in NOT_NUMBERS
    }
    rows = {key.strip() for key in BOUNDS}
    assert numbers == rows, f"[safety] keys without bounds here: {sorted(numbers - rows)}"


@pytest.mark.parametrize("key", sorted(BOUNDS))
def test_a_safety_figure_at_its_bound_is_accepted_and_just_past_it_refused(key: str) -> None:
    at, past = BOUNDS[key]
    assert getattr(_set(key, at).safety, key.strip()) == at
    with pytest.raises(ConfigError, match=rf"\[safety\] {key.strip()}"):
        _set(key, past)


@pytest.mark.parametrize("key", sorted({k.strip() for k in BOUNDS}))
@pytest.mark.parametrize("bad", [math.nan, math.inf, True], ids=["nan", "inf", "bool"])
def test_a_safety_figure_must_be_a_finite_number(key: str, bad: object) -> None:
    with pytest.raises(ConfigError, match=rf"\[safety\] {key}"):
        _set(key, bad)  # type: ignore[arg-type]


def test_the_zero_offset_margin_may_not_exceed_the_deflection_bound() -> None:
    config = load_config()
    bound = config.safety.max_deflection_rad
    assert config.changed("safety", zero_offset_margin_rad=bound).safety.zero_offset_margin_rad
    with pytest.raises(ConfigError, match="zero_offset_margin_rad"):
        config.changed("safety", zero_offset_margin_rad=bound * (1 + TINY))


def test_every_reaction_key_takes_a_reaction_and_on_exit_only_a_torque_state() -> None:
    config = load_config()
    reactions = [name for name in SafetySection.model_fields if name.startswith("on_")]
    for key in reactions:
        with pytest.raises(ConfigError, match=key):
            config.changed("safety", **{key: "panic"})
        assert str(getattr(config.changed("safety", **{key: "hold"}).safety, key)) == "hold"
    with pytest.raises(ConfigError, match="on_exit"):
        config.changed("safety", on_exit="back_off")
