"""USDO client (CiA 1301) of an fd line: `line.usdo`, `remote.usdo`.

    line.usdo.upload(5, 0x1018, 1)                  -> bytes
    line.usdo.download(5, 0x2100, 0, firmware)      # bulk above 4 KiB
    remote = line.add_node(5, od="device.eds")
    remote.od["Producer heartbeat time"].raw = 100  # typed by the OD
    await remote.usdo.aupload("Identity object.Vendor-ID")
    line.usdo.broadcast_upload(0x1000)              -> {node: bytes or UsdoAbortError}

The shared machinery (Transfer, waiting, streams) is in transfer.client,
the remote views in transfer.remote.
"""

from __future__ import annotations

from typing import Any, Dict, Optional

from .._binding.transfers import usdo_abort_to_cia
from .._checks import check_node_id
from ..errors import USDO_ABORT_TEXT, AbortError, TransferAbortError
from ..od import ODVariable
from .client import Transfer, TransferClient

__all__ = ["UsdoAbortError", "UsdoClient", "UsdoTransfer"]

#: A USDO transfer (the shared Transfer class).
UsdoTransfer = Transfer


class UsdoAbortError(TransferAbortError):
    """A USDO transfer ended with an abort: `usdo_code` is the one-byte code
    on the wire, `code` its CiA 301 equivalent (so handlers written for SDO
    keep working); the rest as TransferAbortError."""

    def __init__(self, usdo_code: int, node: int, index: int, subindex: int,
                 from_server: bool, what: str = "") -> None:
        self.usdo_code = usdo_code
        super().__init__(usdo_abort_to_cia(usdo_code),
                         USDO_ABORT_TEXT.get(usdo_code, "unknown abort code"),
                         f"0x{usdo_code:02X}", "USDO", node, index, subindex, from_server, what)


class UsdoClient(TransferClient):
    """The USDO client of one fd line (`line.usdo`)."""

    PROTOCOL = "USDO"
    MODES = ("auto", "expedited", "segmented", "bulk")
    GENERAL_ERROR = 0x10

    def __init__(self, line: Any) -> None:
        super().__init__(line)
        self._client_id: Optional[int] = None

    def _abort_error(self, code: int, node: int, index: int, sub: int, from_server: bool,
                     what: str) -> AbortError:
        return UsdoAbortError(code, node, index, sub, from_server, what)

    def _typed_download(self, variable: ODVariable, options: Dict[str, Any]) -> None:
        options.setdefault("data_type", int(variable.data_type))

    # ------------------------------------------------------------ setup
    @property
    def client_id(self) -> Optional[int]:
        """Our node-id as a USDO client (requests go out on 0x600 + it)."""
        return self._client_id

    @client_id.setter
    def client_id(self, node_id: int) -> None:
        node_id = check_node_id(node_id, f"USDO client id on {self.line._where}")
        self.line._rt.usdo_client(self.line.index, node_id,
                                  f"USDO client id {node_id} on {self.line._where}")
        self._client_id = node_id

    def _ensure_client(self) -> None:
        if self._client_id is None:
            local = self.line.local_node
            # The local node's id, else 127 (a tool with no node of its own).
            self.client_id = local.node_id if local is not None else 127

    def broadcast_upload(self, index: int, sub: int = 0, *,
                         window: float = 0.5) -> Dict[int, Any]:
        """Read index:sub from every server (expedited answers, up to 56
        bytes): {node: bytes or UsdoAbortError} of those that answered
        within `window` seconds."""
        return self.start_upload(0, index, sub, timeout=window).result()

    def broadcast_download(self, index: int, sub: int, data: bytes, *,
                           window: float = 0.5,
                           data_type: Optional[int] = None) -> Dict[int, Any]:
        """Write up to 56 bytes to every server: {node: None or UsdoAbortError}."""
        return self.start_download(0, index, sub, data, mode="expedited", timeout=window,
                                   data_type=data_type).result()
