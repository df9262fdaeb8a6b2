"""Your bench's twin: the emulator fitted to a robot's recorded runs, and its replays checked.

    runs.py       a recorded run read back with what meta.json says it was
    replay.py     a run replayed on an emulator in process: its goals (open loop), or its
                  experiment with its controller (closed loop)
    figures.py    the emulator's figures a twin fits, and the configuration they make
    fit.py        the fit: `hil identify`'s start, the rollout residual, the friction model
                  chosen on held-out samples, intervals, what cannot be trusted
    toml_file.py  the twin as a configuration file
    check.py      replays of runs on the twin and on the default emulator: MAE and rms per
                  joint and signal, report.md
    legs_figures.py  DYROS-JET's legs: the twelve joints' figures, and the configuration
                  they make
    legs.py       the legs' fit: its stages on the suspended excitation, the friction model
                  per joint, what the feet must show (the ankles' gears), intervals, problems
    block_lm.py   the legs' solver: Levenberg-Marquardt on a block Jacobian of whole-robot
                  replays, each joint's step accepted on its own cost
    executor.py   where a fit's replays run: this process, forked processes, or Ray tasks

`hil twin` (hil/cli/twin.py) is the command; docs/twin.md the guide.
"""
