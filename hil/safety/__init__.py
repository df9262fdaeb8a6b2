"""The safety supervisor and its watches (see supervisor.py and watches.py)."""

from hil.safety.supervisor import (
    MAX_NOTICES_PER_KIND,
    ReferenceOutsideLimits,
    SafeState,
    Supervisor,
)
from hil.safety.watches import Reporter, Watch, WatchContext, Watches

__all__ = [
    "MAX_NOTICES_PER_KIND",
    "ReferenceOutsideLimits",
    "Reporter",
    "SafeState",
    "Supervisor",
    "Watch",
    "WatchContext",
    "Watches",
]
