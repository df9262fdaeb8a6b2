"""The physical range of each kind of figure the configuration holds, declared once.

Every number of the file has a range judged at load (exit 2, key named, range said), so that an
absurd but finite figure (`gravity_moment_kg_m = 1e300`, `stiffness_nm_per_rad = 1e-300`) is
refused before the first byte instead of being acted on. Each range is wide enough for every
real joint of the kind this product drives (the H54-200-S500-R on an elastic gear: the testbed,
DYROS-JET's twelve leg joints, `hil identify`'s fits, robustness runs at +-30 % and sweeps) and
says why it ends where it does. The same figure in [model] and in [model.joint.NAME], or in the
emulator's truth, has the same type here. A watch's figure is bounded so that a huge number
cannot switch the watch off: a watch is turned off only by its documented switch.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

# --- the gear and the position servo (Kim et al. (1)-(4); the H54's cascade) -------------------
# K: a soft series-elastic spring (~100 N m/rad) up to a stiff harmonic drive (~1e5 N m/rad);
# stiffer, the gear's mode (sqrt(K / I)) leaves the 200 Hz loop's band and the joint is rigid,
# which the flexible-joint model of (1)-(4) does not describe. Kim et al.: 2000.
Stiffness = Annotated[float, Field(ge=100.0, le=1.0e5)]
# D: 0 (an undamped spring) up to 1e4 N m s/rad (D / K = 5 s at K = 2000: a dashpot, not a
# spring). Kim et al.: 100.
Damping = Annotated[float, Field(ge=0.0, le=1.0e4)]
# Kp of (4) and the cascade's position gain Kpp [1/s]: below 0.1 (a 10 s time constant) the
# servo holds no load; above 1000 it is faster than the H54's ~50 Hz velocity loop (314 rad/s)
# can follow, so no first-order reading describes it. Kim et al.: 10; the lab's knees: 18.
ServoGain = Annotated[float, Field(ge=0.1, le=1000.0)]
# kv [N m s/rad]: the velocity loop's bandwidth times the rotor's reflected inertia (the H54:
# 2 pi 50 Hz x 0.25 = 78.5), over the range of both below.
VelocityGain = Annotated[float, Field(ge=0.1, le=1.0e4)]
# Ti [s]: from 1 ms (the H54's velocity-loop period) to 1e4 s (an integral that takes hours to
# act: none at all). The H54's stock registers: 15 s.
IntegralTime = Annotated[float, Field(ge=1.0e-3, le=1.0e4)]
# The rotor's inertia reflected to the output [kg m^2]: 0.25 for the H54's 501:1 gear; 1e-4
# is a small actuator's, 10 forty times the H54's.
RotorInertia = Annotated[float, Field(ge=1.0e-4, le=10.0)]
# The gearbox's viscous friction [N m s/rad] (H54: 1.14) and its Coulomb friction [N m]
# (3.95): 0 up to 100, more than the H54's 44.7 N m continuous torque at 1 rad/s.
ViscousFriction = Annotated[float, Field(ge=0.0, le=100.0)]
CoulombFriction = Annotated[float, Field(ge=0.0, le=100.0)]

# --- the 1-DoF link (the testbed's model: Sm = 1 / I, tau_g = m g r cos q) ---------------------
# I [kg m^2]: from a 0.1 kg, 0.3 m link (1e-3) to 100 (10 kg at 3 m, beyond what an H54 swings).
# The testbed: 0.376.
LinkInertia = Annotated[float, Field(ge=1.0e-3, le=100.0)]
# m r [kg m]: its weight's moment; 9.81 m r must stay within what the actuator holds: 4.5 kg m is
# 44 N m, the H54-200-S500-R's continuous torque (44.7 N m, e-Manual). A heavier link cannot be
# held, and its gravity compensation would drive the goal into the limits (1e300 did, at 172 N
# against the block). The testbed: 0.63.
GravityMoment = Annotated[float, Field(ge=0.0, le=4.5)]

# --- angles of the emulated world ---------------------------------------------------------------
# An angle a joint starts at or is welded at [rad]: within half a turn either side (a joint's
# [[joint]] limits and offsets are the drivers' to judge: the H54's position-mode range).
Angle = Annotated[float, Field(ge=-3.15, le=3.15)]

# --- watches of the safety supervisor, counted in ticks ------------------------------------------
# A streak of ticks a watch tolerates: at most 200 (1 s at Kim et al.'s 200 Hz); a joint whose
# actuator or link encoder has been silent for longer runs blind.
WatchTicks = Annotated[int, Field(ge=1, le=200)]
# A window of ticks a watch counts over: at most 2000 (10 s at 200 Hz).
WatchWindowTicks = Annotated[int, Field(ge=1, le=2000)]

# --- the LQR's weights (Kim et al.: Q = 10 I, R = I) ---------------------------------------------
# They act by their ratios; within 1e-6 .. 1e6 each the Riccati equation stays well inside double
# precision (a weight of 1e300 made it singular). DYROS-JET's configuration: R = 1e5.
LqrWeight = Annotated[float, Field(ge=1.0e-6, le=1.0e6)]
LqrWeightOrZero = Annotated[float, Field(ge=0.0, le=1.0e6)]

# --- the DOB's gain ------------------------------------------------------------------------------
# Kdist: the share of the estimated disturbance fed back; the paper's largest is 1, the
# supervisor runs nothing above [safety] max_kdist (1 by default). 10 bounds both: a DOB that
# feeds back ten times what it estimates is no disturbance observer.
Kdist = Annotated[float, Field(ge=0.0, le=10.0)]
