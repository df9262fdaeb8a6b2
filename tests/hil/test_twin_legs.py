"""The done-when measurement of issue 28 on DYROS-JET's legs: legs whose hardware is not the
default emulator, their twin fitted from one suspended excitation, checked on held-out runs on
the feet.

The "hardware" (tests/support/legs_hardware.py LEGS_TRUTH_EMULATOR, never given to the fit):
each joint's K, D, servo gains, rotor, friction (its model too, on half the joints) and encoder
zeros, and the robot's mass, differ from the default emulator's. On it, with the host's
configuration (the default dyros_jet.toml, which meta.json records): one `suspended-chirp` run
and one `push` run with pid (the fit's inputs: hung, the ankles' gears carry only the feet and
are not seen, so they are fitted on the feet), and held out: `stand` with pid and gc+lqr+dob,
`walk-slow` with gc+lqr+dob. Then:
- the fit ends trusted or says why (its problems are printed);
- each held-out run replayed on the twin has, on every joint, a lower link-angle MAE than on
  the default emulator: open loop (the recorded goals) every run, closed loop (the recorded
  controller on the recorded experiment) the stands; the walk closed loop is chaotic (a
  figure's 14th digit moves a joint's MAE by 2x), so there the mean over the joints is judged
  and each joint's printed.

Run with -s for the table (docs/twin.md's figures come from it):
    .venv/bin/pytest -q -s -m faults tests/hil/test_twin_legs.py
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from hil.config import load_config
from hil.twin.check import Emulator, Loop
from hil.twin.legs import LegsFitOptions, fit_legs
from hil.twin.runs import read_run
from hil.twin.toml_file import write_config
from hil.vocabulary import Robot
from tests.support.bench_hardware import record
from tests.support.legs_hardware import legs_truth_config

# the fit replays the 66 s excitation some 150 times, two at a time: ~9-12 min on 2 cores
pytestmark = [pytest.mark.faults, pytest.mark.slow, pytest.mark.timeout(3000)]

FITTED = ("suspended-chirp", "push")  # hung, then on the feet (with pid)
HELD_OUT = (("stand", "pid"), ("stand", "gc+lqr+dob"), ("walk-slow", "gc+lqr+dob"))


@pytest.fixture(scope="module")
def legs(tmp_path_factory: pytest.TempPathFactory) -> dict:
    root = tmp_path_factory.mktemp("legs")
    host = load_config(robot=Robot.DYROS_JET)
    truth = legs_truth_config(host)
    fitted = [record(truth, host, name, "pid", root / "fit") for name in FITTED]
    assert all(r.termination == "completed" for r in fitted)
    held = []
    for experiment, controller in HELD_OUT:
        result = record(truth, host, experiment, controller, root / "held")
        assert result.termination == "completed", (experiment, controller)
        held.append(result.out_dir)
    fit = fit_legs([read_run(r.out_dir) for r in fitted], LegsFitOptions(workers=2))
    twin = write_config(fit.config, root / "twin.toml")
    # the check as a user runs it, in a process of its own
    done = subprocess.run(
        [sys.executable, "-m", "hil", "twin", "--check", str(twin), *map(str, held),
         "--out", str(root / "check"), "--json"],
        capture_output=True, text=True, timeout=1800,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    check = json.loads(done.stdout.strip().splitlines()[-1])
    return {"fit": fit, "check": check, "truth": truth}


def test_the_fit_says_whether_it_can_be_trusted(legs: dict) -> None:
    fit = legs["fit"]
    print("\nproblems:", *fit.problems, sep="\n  ")
    assert fit.estimates and fit.held_out_rms
    assert fit.trusted == (not fit.problems)


def test_every_joint_replays_closer_on_the_twin_than_on_the_default(legs: dict) -> None:
    residuals = legs["check"]["residuals"]
    twin, default = Emulator.TWIN.value, Emulator.DEFAULT.value
    failures = []
    print()
    for loop in (Loop.CLOSED.value, Loop.OPEN.value):
        for run in sorted({r["run"] for r in residuals}):
            pairs: dict[str, dict[str, float]] = {}
            for r in residuals:
                if r["run"] == run and r["loop"] == loop and r["signal"] == "link_angle_rad":
                    pairs.setdefault(r["joint"], {})[r["emulator"]] = r["mae"]
            worst = max(pairs, key=lambda j: pairs[j][twin] / pairs[j][default])
            ratio = pairs[worst][twin] / pairs[worst][default]
            print(f"{loop:12s} {run:45s} worst joint {worst}: twin/default {ratio:.3f}")
            if loop == Loop.CLOSED.value and "walk" in run:
                # A walk closed loop is chaotic: twins whose figures differ in the 14th digit
                # (this fit alone, or in the fault suite after other tests) replay it with a
                # left hip roll of 1.10 or 2.59 mrad (the default: 2.02), the other joints
                # 0.5-3.5 or 1.5-8.0. Per joint it is reported, not judged; the mean is.
                mean = {e: sum(p[e] for p in pairs.values()) / len(pairs) for e in (twin, default)}
                print(f"{'':12s} {'':45s} mean: twin {mean[twin]:.3f}, default {mean[default]:.3f}")
                failures += [] if mean[twin] < mean[default] else [(loop, run, "mean")]
                continue
            failures += [(loop, run, j) for j, p in pairs.items() if not p[twin] < p[default]]
    assert not failures, failures
