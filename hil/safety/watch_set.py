"""The supervisor's watches as one set, in the order they run on each tick's sample (for one
joint: actuator, link, deflection - the order of the events); hil/safety/watches.py and
link_watches.py say what each watches."""

from __future__ import annotations

from dataclasses import dataclass

from hil.safety.link_watches import LinkHistory, LinkNoiseWatch, LinkStaleWatch
from hil.safety.overload import GuardRule
from hil.safety.watches import (
    ActuatorFaultWatch,
    BusErrorWatch,
    CurrentGuardWatch,
    DeflectionWatch,
    OverrunWatch,
    Watch,
    WatchContext,
)


@dataclass
class Watches:
    """The sample watches in their order, plus the two the supervisor talks to directly."""

    bus: BusErrorWatch
    actuator: ActuatorFaultWatch
    current: CurrentGuardWatch
    link_stale: LinkStaleWatch
    link_noise: LinkNoiseWatch
    deflection: DeflectionWatch
    overrun: OverrunWatch

    @classmethod
    def default(cls, context: WatchContext, guard: GuardRule) -> Watches:
        history = LinkHistory(context.n_joints)
        return cls(
            bus=BusErrorWatch(context),
            actuator=ActuatorFaultWatch(context),
            current=CurrentGuardWatch(context, guard),
            link_stale=LinkStaleWatch(context, history),
            link_noise=LinkNoiseWatch(context, history),
            deflection=DeflectionWatch(context),
            overrun=OverrunWatch(context),
        )

    @property
    def in_order(self) -> tuple[Watch, ...]:
        return (
            self.bus,
            self.actuator,
            self.current,
            self.link_stale,
            self.link_noise,
            self.deflection,
        )
