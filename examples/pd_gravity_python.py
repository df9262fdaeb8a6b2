"""The PD + gravity feed-forward plug-in (examples/pd_gravity.py) run from Python: on the
emulated testbed's contact and impact experiments and on the emulated DYROS-JET standing,
each exactly as `hil run EXPERIMENT --controller examples/pd_gravity.py:PdGravity` does.

    python examples/pd_gravity_python.py
"""

import os

import hil

PD = "examples/pd_gravity.py:PdGravity"
out = os.environ.get("HIL_EXAMPLE_OUT", "runs")

testbed = hil.open_robot(robot="testbed", out_root=out)
for experiment in ("contact", "impact"):
    result = testbed.run(experiment, PD)
    print(f"{experiment}: {result.ending}; {result.metrics}")

humanoid = hil.open_robot(robot="dyros-jet", out_root=out)
stand = humanoid.run("stand", PD, duration_s=3.0)
print(f"stand: {stand.ending}; fell = {stand.metrics['fell']}")
raise SystemExit(stand.exit_status)
