"""Running redundik at a fixed rate: the control-loop runner (:class:`ControlLoop`, :mod:`redundik.control.loop`) and
the command watchdog (:class:`Watchdog`, :mod:`redundik.resolvers.watchdog`)."""

from redundik.control.loop import ControlLoop, DeadlineStats, Tick, deadline_stats
from redundik.resolvers.watchdog import Watchdog

__all__ = ["ControlLoop", "DeadlineStats", "Tick", "Watchdog", "deadline_stats"]
