"""The safety supervisor and its watches (see supervisor.py, watches.py and link_watches.py), the
actuators' overload protection the current guard derives from (overload.py).
How an experiment's robot does the reactions is hil.vocabulary's `ReactionPolicy`."""

from hil.safety.overload import GuardRule, OverloadProtection, protection_of, protections_of
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
    "GuardRule",
    "OverloadProtection",
    "ReferenceOutsideLimits",
    "Reporter",
    "SafeState",
    "Supervisor",
    "Watch",
    "WatchContext",
    "Watches",
    "protection_of",
    "protections_of",
]
