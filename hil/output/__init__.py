"""What a run leaves behind: the run log, run directories, plots and the comparison report.

The bottom of `hil`: it imports no device library (no MuJoCo, dynamixel-sdk, python-can or
canopen), so reading and plotting runs works anywhere.
"""

from hil.output.records import RunEntry, RunResult
from hil.output.rundir import RunData, create_run_dir, load_run, timestamp, unique_dir
from hil.output.runlog import PER_JOINT_COLUMNS, RunLog, read_log

__all__ = [
    "PER_JOINT_COLUMNS",
    "RunData",
    "RunEntry",
    "RunLog",
    "RunResult",
    "create_run_dir",
    "load_run",
    "read_log",
    "timestamp",
    "unique_dir",
]
