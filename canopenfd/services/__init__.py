"""The services of lines and nodes; each takes a narrow line context, never a Line.

nmt (NMT master and slave, heartbeat), emcy, pdo, sync, time, guard (node
guarding), sleep (sleep and wake-up, CiA 320), redundancy (bus redundancy over two buses), indications (on_read / on_write), store (parameter stores),
served_od (the local node's values, domains and change callbacks), manager
(CiA 302-2 network start-up); views:
what services see of their node (Protocols).
"""

from .guard import GuardEvent
from .manager import ManagerEvent, NetworkManager, NetworkStartError
from .redundancy import BusRedundancy, RedundancyNotice, redundancy_record
from .sleep import SleepNotice, SleepService
from .sync import SyncService
from .time import TIME_EPOCH, TimeService

__all__ = ["BusRedundancy", "RedundancyNotice", "redundancy_record", "SleepNotice", "SleepService", "SyncService", "TimeService", "GuardEvent",
           "TIME_EPOCH", "ManagerEvent", "NetworkManager", "NetworkStartError"]
