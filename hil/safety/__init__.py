"""The safety supervisor and its watches (see supervisor.py, watches.py and link_watches.py)."""

from hil.safety.supervisor import (
    MAX_NOTICES_PER_KIND,
    ReferenceOutsideLimits,
    SafeState,
    Supervisor,
)
from hil.safety.watch_set import Watches
from hil.safety.watches import Reporter, Watch, WatchContext

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
