"""Parameter sweeps on Ray: where do the paper's relations hold as the plant and gains change?

    spec.py       the sweep specification (TOML; shipped ones in hil/data/sweeps) and its plan
    task.py       one run, as a worker runs it: `Session.run_one`, lock-step, its row always
    table.py      results.csv, appended per finished run; what a rerun skips
    relations.py  the paper's relations at every point, and the fraction where each holds
    maps.py       maps/<experiment>.png: where each relation holds over two parameters
    identity.py   what shapes every run (the base configuration too): sweep.json, a resume's check
    lock.py       one sweep at a time in an output directory
    interrupts.py Ctrl-C and SIGTERM at every moment of a sweep
    engine.py     Ray (local or a cluster), progress with ETA, the findings
    bench.py      runs per minute with 1 and 2 workers, and the engine's per-run overhead

Ray is an optional extra (`pip install -e '.[sweep]'`); only engine.py and bench.py import it,
when they run.
"""

from hil.sweep.engine import (
    INSTALL_HINT,
    ClusterUnreachable,
    RayMissing,
    SweepInterrupted,
    SweepOutcome,
    fractions_text,
    import_ray,
    run_sweep,
)
from hil.sweep.identity import SweepMismatch
from hil.sweep.lock import SweepBusy
from hil.sweep.plan import plan
from hil.sweep.spec import (
    ModelFollows,
    Sampling,
    SpecError,
    SweepParameter,
    SweepSetup,
    SweepSpec,
    Task,
    load_spec,
    parse_spec,
    shipped_specs,
)
from hil.sweep.table import ResultsTable, TableMismatch

__all__ = [
    "INSTALL_HINT",
    "ClusterUnreachable",
    "ModelFollows",
    "RayMissing",
    "ResultsTable",
    "Sampling",
    "SpecError",
    "SweepBusy",
    "SweepInterrupted",
    "SweepMismatch",
    "SweepOutcome",
    "SweepParameter",
    "SweepSetup",
    "SweepSpec",
    "TableMismatch",
    "Task",
    "fractions_text",
    "import_ray",
    "load_spec",
    "parse_spec",
    "plan",
    "run_sweep",
    "shipped_specs",
]
