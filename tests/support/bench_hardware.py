"""A bench's "hardware" that is not the default emulator, for the twin's tests: a configuration
file whose [emulator] (and zero errors) differ from the host's, never given to the fit.

`record(truth, host, experiment, controller, out_root)` runs one experiment the way `hil run`
does with the host's configuration, on the emulated hardware the truth's configuration
describes: through the emulated buses (`hil emulate --config TRUTH` in its own process, the run
attached to it: the real path), or in process (the in-process bus of the host's configuration
over the truth's emulated devices: fast). meta.json records the host's configuration, as on a
real bench: the truth is not in the record.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

from hil.config import Config
from hil.controllers.choice import choose
from hil.experiments import Experiment
from hil.output.records import RunResult
from hil.robots import get_experiment
from hil.session import session as session_module
from hil.session.session import ConnectionOverrides, Session, Setup
from hil.wiring.emulation import EmbeddedEmulator, emulator_spec
from hil.wiring.in_process import InProcessJointBus

# The bench of the done-when measurement (issue 28): every figure the fit recovers differs from
# the default emulator's, and the gearbox's friction is load-dependent.
TRUTH_EMULATOR = {
    "plant": {
        "gear_stiffness_nm_per_rad": 1700.0,
        "gear_damping_nms_per_rad": 70.0,
        "motor_reflected_inertia_kg_m2": 0.21,
        "gearbox_coulomb_friction_nm": 2.6,
        "gearbox_viscous_friction_nms_per_rad": 1.6,
        "gearbox_friction_model": "load-dependent",
        "gearbox_load_friction_ratio": 0.12,
        "link_mass_kg": 0.95,
        "load_mass_kg": 0.65,
    },
    "servo": {
        "position_gain_per_s": 12.5,
        "velocity_gain_nms_per_rad": 64.0,
        "velocity_integral_time_s": 9.0,
    },
    # the motor's zero calibrated with the gear loaded (it took the gravity deflection), the
    # link's a level's reading off
    "motor_zero_error_rad": -2.5e-3,
    "link_zero_error_rad": 3.0e-4,
}


def truth_config(host: Config, emulator: dict | None = None) -> Config:
    values = TRUTH_EMULATOR if emulator is None else emulator
    return host.changed("emulator", **values)


@contextlib.contextmanager
def _in_process_on(truth: Config) -> Iterator[None]:
    def bus(config: Config, experiment: Experiment | None, faults: tuple, seed: int | None = None):
        return InProcessJointBus(
            config, emulator_spec(truth, experiment=experiment, faults=faults, seed=seed)
        )

    with mock.patch.object(session_module, "in_process_bus", bus):
        yield


def record(
    truth: Config,
    host: Config,
    experiment: str,
    controller: str,
    out_root: Path,
    *,
    buses: bool = False,
    kdist: float | None = None,
    duration_s: float | None = None,
) -> RunResult:
    """One run of `experiment` with `controller` (host's configuration) on the truth's hardware."""
    chosen = get_experiment(experiment)
    if kdist is not None:
        host = host.changed("controller", kdist=kdist)
    choice = choose(controller, host, chosen)
    if not buses:
        with _in_process_on(truth):
            session = Session(
                host, Setup.IN_PROCESS, out_root=out_root, plots=False, quiet=True, mcap=False
            )
            return session.run_one(chosen, choice, duration_s=duration_s, print_result=False)
    with EmbeddedEmulator(emulator_spec(truth, experiment=chosen)) as emulator:
        session = Session(
            host,
            Setup.ATTACHED,
            attach=emulator.endpoints,
            overrides=ConnectionOverrides(),
            out_root=out_root,
            plots=False,
            quiet=True,
            mcap=False,
        )
        return session.run_one(chosen, choice, duration_s=duration_s, print_result=False)
