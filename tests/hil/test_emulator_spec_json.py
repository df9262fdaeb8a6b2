"""The emulator's spec crosses to the `hil emulate` child as JSON: every field must survive."""

from __future__ import annotations

import dataclasses

from hil.config import load_config
from hil.experiments import CONTACT, PUSH
from hil.vocabulary import EmulatorClock
from hil.wiring.emulation import emulator_spec, spec_from_json, spec_to_json
from sim_backend.scenario import FaultEvent


def _not_default(config):
    # every scalar the JSON must carry set to something other than its default
    emulator = config.emulator.model_copy(
        update={"usb_latency_timer_ms": 4.0, "seed": 11, "reboot_time_s": 0.7}
    )
    return config.replaced(emulator=emulator)


def test_a_testbed_spec_survives_the_round_trip() -> None:
    config = _not_default(load_config())
    faults = (FaultEvent("noisy_encoder", 1.0, 0.5, noise_counts_rms=3.0),)
    spec = emulator_spec(config, experiment=CONTACT, faults=faults, clock=EmulatorClock.REALTIME)
    spec = dataclasses.replace(spec, can_bootup_delay_s=0.02)
    assert spec.usb_latency_timer_s == 0.004
    assert spec_from_json(spec_to_json(spec)) == spec


def test_a_humanoid_spec_survives_the_round_trip() -> None:
    config = _not_default(load_config(robot="dyros-jet"))
    spec = emulator_spec(config, experiment=PUSH)
    assert spec_from_json(spec_to_json(spec)) == spec
