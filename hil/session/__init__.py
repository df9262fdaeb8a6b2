"""Where runs happen: one run on a setup (`Session`), and the paper's comparison."""

from hil.session.comparison import ComparisonOutcome, run_comparison
from hil.session.session import ConnectionOverrides, Session, SessionError, Setup

__all__ = [
    "ComparisonOutcome",
    "ConnectionOverrides",
    "Session",
    "SessionError",
    "Setup",
    "run_comparison",
]
