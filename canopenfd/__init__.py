"""canopenfd: a CANopen FD (CiA 1301) and classic CANopen (CiA 301) stack.

The protocol runs in a C core on its own thread; this package is the Python
facade over it::

    import canopenfd

    with canopenfd.Network() as net:
        line = net.open_line("mem:demo", mode="fd")
        me = line.create_local_node(1, heartbeat_ms=100)
        drive = line.add_node(5, heartbeat_timeout_ms=300)
        line.nmt.start(5)
"""

__version__ = "0.1.0"

from ._binding.constants import CommEvent
from .connect import connect
from .decode import decode
from .errors import (AbortError, CanopenFDError, ClosedError, CommandError, ConfigurationError,
                     InterfaceError)
from .frame import Frame
from .line import Line
from .network import Network
from .node import LocalNode, LocalValue, RemoteNode
from .od import ObjectDictionary, OdFileError, OdValueError, import_od
from .services.emcy import Emcy
from .services.indications import ODRequest
from .services.flyma import FlymaEvent, FlymaNotice, FlymaState
from .services.nmt import NmtCommand, NmtState
from .services.redundancy import RedundancyEvent, RedundancyNotice
from .services.sleep import SleepCause, SleepEvent, SleepNotice, SleepPhase
from .transfer import SdoAbortError, Transfer, UsdoAbortError, UsdoTransfer

__all__ = [
    "__version__",
    "AbortError", "CanopenFDError", "ClosedError", "CommandError", "ConfigurationError",
    "InterfaceError", "OdFileError", "OdValueError", "ObjectDictionary", "import_od", "LocalValue",
    "Frame", "Emcy", "NmtCommand", "NmtState", "decode",
    "Network", "Line", "connect", "CommEvent", "LocalNode", "RemoteNode", "ODRequest",
    "UsdoAbortError", "UsdoTransfer", "SdoAbortError", "Transfer",
    "SleepCause", "SleepEvent", "SleepNotice", "SleepPhase",
    "FlymaEvent", "FlymaNotice", "FlymaState",
    "RedundancyEvent", "RedundancyNotice",
]
