"""USDO client (CiA 1301) of an fd line: `line.usdo`, `remote.usdo`.

    line.usdo.upload(5, 0x1018, 1)                  -> bytes
    line.usdo.download(5, 0x2100, 0, firmware)      # bulk above 4 KiB
    line.usdo.upload(5, 0x2100, 0, mode="bulk")     # the server streams (size_hint= for AUTO)
    remote = line.add_node(5, od="device.eds")
    remote.od["Producer heartbeat time"].raw = 100  # typed by the OD
    await remote.usdo.aupload("Identity object.Vendor-ID")
    line.usdo.broadcast_upload(0x1000)              -> {node: bytes or UsdoAbortError}

The shared machinery (Transfer, waiting, streams) is in transfer.client,
the remote views in transfer.remote.
"""

from __future__ import annotations

from typing import Dict, Optional, Union, cast

from .._binding.context import LineContext
from .._binding.transfers import usdo_abort_to_cia
from .._checks import check_node_id
from ..errors import USDO_ABORT_TEXT, AbortError, TransferAbortError
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
    #: uploads: 'auto' (bulk from a size hint of 4 KiB on, else the server
    #: picks expedited or segmented) or 'bulk' (the server streams in our
    #: window; a server without bulk refuses it with 0x13)
    UPLOAD_MODES = ("auto", "bulk")
    HINTS_UPLOAD_SIZE = True
    # CO_USDO_ABORT_UNKNOWN (co_usdo_abort_t is outside the cdef; tests compare it)
    GENERAL_ERROR = 0x10
    SENDS_DATA_TYPE = True

    def __init__(self, context: LineContext) -> None:
        super().__init__(context)
        self._client_id: Optional[int] = None

    def _abort_error(self, code: int, node: int, index: int, sub: int, from_server: bool,
                     what: str) -> AbortError:
        return UsdoAbortError(code, node, index, sub, from_server, what)

    # ------------------------------------------------------------ setup
    @property
    def client_id(self) -> Optional[int]:
        """Our node-id as a USDO client (requests go out on 0x600 + it)."""
        return self._client_id

    @client_id.setter
    def client_id(self, node_id: int) -> None:
        context = self._context
        node_id = check_node_id(node_id, f"USDO client id on {context.where}")
        context.runtime.usdo_client(context.index, node_id,
                                    f"USDO client id {node_id} on {context.where}")
        self._client_id = node_id

    def _ensure_client(self) -> None:
        if self._client_id is None:
            local = self._context.local_node_id
            # The local node's id, else 127 (a tool with no node of its own).
            self.client_id = local if local is not None else 127

    def broadcast_upload(self, index: int, sub: int = 0, *,
                         window: float = 0.5) -> Dict[int, Union[bytes, AbortError]]:
        """Read index:sub from every server (expedited answers, up to 56
        bytes): {node: bytes or UsdoAbortError} of those that answered
        within `window` seconds."""
        answers = self.start_upload(0, index, sub, timeout=window).result()
        # node 0: the engine's {node: answer}, an upload's answers are bytes or an abort
        return cast(Dict[int, Union[bytes, AbortError]], answers)

    def broadcast_download(self, index: int, sub: int, data: bytes, *,
                           window: float = 0.5,
                           data_type: Union[None, int, str] = None
                           ) -> Dict[int, Optional[AbortError]]:
        """Write up to 56 bytes to every server: {node: None or UsdoAbortError}."""
        answers = self.start_download(0, index, sub, data, mode="expedited", timeout=window,
                                      data_type=data_type).result()
        # node 0: the engine's {node: answer}, a download's answers are None or an abort
        return cast(Dict[int, Optional[AbortError]], answers)
