"""Your own experiment: the testbed's link swung along a sine, with its own metric.

    hil run examples/sine_experiment.py:Sine --controller pid
    hil run examples/sine_experiment.py:Sine --controller examples/pd_gravity.py:PdGravity

An experiment is a frozen dataclass (hil/experiments/base.py lists every hook): the reference
the joints follow (here `reference`), the world the emulator builds (none: the link swings
free), and the metrics computed from the run's log at its end.
"""

import math
from dataclasses import dataclass

import numpy as np

from hil.experiments import Experiment, World
from hil.output.rundir import RunData


@dataclass(frozen=True)
class Sine(Experiment):
    """0.2 rad at 0.5 Hz about the horizontal, after a one-second ramp of its amplitude."""

    name: str = "sine"
    title: str = "A sine on the link"
    duration_s: float = 6.0
    amplitude_rad: float = 0.2
    frequency_hz: float = 0.5
    world: World = World()

    def reference(self, time_s: float) -> float:
        ramp = min(max(time_s, 0.0), 1.0)
        return ramp * self.amplitude_rad * math.sin(2 * math.pi * self.frequency_hz * time_s)

    def reference_range(self, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
        return np.full(n_joints, -self.amplitude_rad), np.full(n_joints, self.amplitude_rad)

    def metrics(self, run: RunData) -> dict[str, float]:
        tracking = run.time_s >= run.experiment_start_s + 1.0
        error = run.signal("link_angle_rad") - run.signal("reference_rad")
        return {
            "rms_error_rad": float(np.sqrt(np.mean(error[tracking] ** 2))),
            "max_error_rad": float(np.max(np.abs(error[tracking]))),
        }
