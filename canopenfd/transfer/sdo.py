"""SDO client (CiA 301) of a classic line: `line.sdo`, `remote.sdo`.

    line.sdo.upload(5, 0x1018, 1)                   -> bytes
    line.sdo.download(5, 0x2100, 0, firmware)       # block transfer from 1 KiB
    remote = line.add_node(5, od="device.eds")
    remote.od["Producer heartbeat time"].raw = 100  # typed by the OD
    await remote.sdo.aupload("Identity object.Vendor-ID")

Expedited, segmented and block transfers (CRC, sub-block repetition) run in
the C core; see transfer.client for waiting, streams and progress.
"""

from __future__ import annotations

from typing import Optional

from .._binding.constants import AbortCode
from .._binding.context import LineContext
from .._binding.transfers import TransferRequest
from ..errors import ABORT_TEXT, AbortError, ConfigurationError, TransferAbortError
from .client import Route, TransferClient

__all__ = ["SdoAbortError", "SdoClient"]

#: A block transfer from this many bytes on (AUTO), unless told otherwise.
DEFAULT_BLOCK_THRESHOLD = 1024


class SdoAbortError(TransferAbortError):
    """An SDO transfer ended with an abort (see TransferAbortError)."""

    def __init__(self, code: int, node: int, index: int, subindex: int, from_server: bool,
                 what: str = "") -> None:
        super().__init__(code, ABORT_TEXT.get(code, "unknown abort code"), f"0x{code:08X}",
                         "SDO", node, index, subindex, from_server, what)


class SdoClient(TransferClient):
    """The SDO client of one classic line (`line.sdo`): transfers to several
    servers run at once (one per server on its default channel)."""

    PROTOCOL = "SDO"
    MODES = ("auto", "expedited", "segmented", "block")
    UPLOAD_MODES = MODES
    GENERAL_ERROR = int(AbortCode.GENERAL)

    def __init__(self, context: LineContext) -> None:
        super().__init__(context)
        #: AUTO picks block transfer from this size on (None: never).
        self.block_threshold: Optional[int] = DEFAULT_BLOCK_THRESHOLD

    def _abort_error(self, code: int, node: int, index: int, sub: int, from_server: bool,
                     what: str) -> AbortError:
        return SdoAbortError(code, node, index, sub, from_server, what)

    def _request(self, node: int, index: int, sub: int, upload: bool, timeout: float,
                 what: str, route: Optional[Route] = None) -> TransferRequest:
        request = super()._request(node, index, sub, upload, timeout, what, route)
        threshold = self.block_threshold
        if threshold is not None and (isinstance(threshold, bool) or
                                      not isinstance(threshold, int) or
                                      not 1 <= threshold < 0xFFFFFFFF):
            raise ConfigurationError(f"{what}: block_threshold must be None or 1..2^32-2, "
                                     f"got {threshold!r}")
        request.block_threshold = 0xFFFFFFFF if threshold is None else threshold
        return request
