"""The client side of SDO (classic lines) and USDO (fd lines), and the remote
object dictionary views built on it.

- `client`: what both share: `Transfer` (result, await, cancel), `TransferClient`
- `usdo`: `UsdoClient` (`line.usdo`: broadcast, client id), `UsdoAbortError`
- `sdo`: `SdoClient` (`line.sdo`: block threshold), `SdoAbortError`
- `remote`: `remote.usdo` / `remote.sdo` (`RemoteAccess`), `remote.od[key]` (`RemoteValue`)
"""

from .client import Transfer, TransferClient
from .remote import RemoteAccess, RemoteObjects, RemoteValue, resolve
from .sdo import SdoAbortError, SdoClient
from .usdo import UsdoAbortError, UsdoClient, UsdoTransfer

__all__ = ["Transfer", "TransferClient", "RemoteAccess", "RemoteObjects", "RemoteValue",
           "resolve", "SdoAbortError", "SdoClient", "UsdoAbortError", "UsdoClient",
           "UsdoTransfer"]
