"""Client transfers (USDO, SDO) as the C runtime takes them.

`TransferRequest` holds a request in Python values; the runtime wrapper turns
it into a `co_rt_transfer_request_t` when it starts the transfer. Data to
download from memory is handed over as a keep-alive buffer the caller holds
until the transfer ended (the runtime thread reads it in place, no copy).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple

from .core import CData, ffi, lib

__all__ = ["TransferRequest", "CBuffer", "memory_source", "usdo_abort_to_cia"]

#: A cffi buffer over the caller's bytes-like object; keep it alive while the
#: transfer runs.
CBuffer = CData


@dataclass
class TransferRequest:
    """One client transfer (the fields of co_rt_transfer_request_t)."""

    server: int                       # node-id 1..127; USDO: 0 = broadcast
    index: int
    sub: int
    upload: bool
    timeout_ms: int                   # per frame; broadcast: the answer window
    mode: int = 0                     # 0 auto, then the protocol's modes
    data_type: int = 0                # USDO download: CiA 301 type byte
    data: Optional[CBuffer] = None    # download from memory (see memory_source)
    size: int = 0                     # download: bytes; SDO upload: expected size
    fd: int = -1                      # >= 0: download from / upload to this file ...
    fd_offset: int = 0                # ... from this offset
    max_size: int = 0                 # upload to memory: largest accepted (0 = default)
    block_threshold: int = 0          # SDO AUTO: block from this size
    progress: bool = False            # post progress events
    done_event: bool = False          # post TRANSFER_DONE (else: ask with transfer_notify)
    network: int = 0                  # SDO networking: node network_node of this network
    network_node: int = 0             # through the gateway `server` (0: the server itself)

    def to_c(self) -> CData:
        """The co_rt_transfer_request_t (cdata) of this request."""
        request = ffi.new("co_rt_transfer_request_t *")
        request.server = self.server
        request.index = self.index
        request.sub = self.sub
        request.upload = int(self.upload)
        request.mode = self.mode
        request.type = self.data_type
        if self.data is not None:
            request.data = self.data
        request.size = self.size
        request.fd = self.fd
        request.fd_offset = self.fd_offset
        request.max_size = self.max_size
        request.timeout_ms = self.timeout_ms
        request.block_threshold = self.block_threshold
        request.progress = int(self.progress)
        request.no_done_event = int(not self.done_event)
        request.network = self.network
        request.network_node = self.network_node
        return request


def memory_source(data: object) -> Tuple[CBuffer, int]:
    """(keep-alive buffer, size in bytes) of bytes-like `data`; TypeError when
    it is not bytes-like."""
    buffer = ffi.from_buffer(data)
    return buffer, len(buffer)


def usdo_abort_to_cia(usdo_code: int) -> int:
    """The CiA 301 abort code of a one-byte USDO abort code (the core's mapping)."""
    return lib.co_usdo_abort_to_co(usdo_code)
