"""A raw 200 Hz loop of your own through the public API: a sine on the testbed's link, every
goal through the safety supervisor, the run recorded like `hil run`'s.

    python examples/sine_loop.py            # the embedded emulated testbed, lock-step

On the real testbed: `hil.open_robot("my_testbed.toml", setup=hil.Setup.HARDWARE)` (the wall
clock, the same code).
"""

import math
import os

import hil

AMPLITUDE_RAD = 0.2
FREQUENCY_HZ = 0.5

robot = hil.open_robot(robot="testbed", out_root=os.environ.get("HIL_EXAMPLE_OUT", "runs"))
peak_rad = 0.0
with robot.loop("sine", duration_s=4.0) as loop:
    for sample in loop:  # one JointSample a tick, in SI units
        peak_rad = max(peak_rad, abs(float(sample.link_angle_rad[0])))
        ramp = min(loop.time_s, 1.0)  # the amplitude ramped in over a second
        reference = ramp * AMPLITUDE_RAD * math.sin(2 * math.pi * FREQUENCY_HZ * loop.time_s)
        loop.cycle_actuation([reference])  # the goal motor angle [rad], one per joint
        loop.end_cycle(reference_rad=[reference])  # logged as the reference

result = loop.result
print(f"{result.ending}: {result.ticks} ticks in {result.out_dir}; link peak {peak_rad:.3f} rad")
raise SystemExit(result.exit_status)
