"""`Decoder`: the frame decoder `canopenfd monitor` keeps for its lifetime."""

from __future__ import annotations

from typing import Any, Iterable, Optional, Tuple

from .classify import Classified, frame_service
from .dispatch import DecoderState, decoded_line, described_line, frame_meaning


class Decoder:
    """A frame decoder that follows what needs earlier frames, and decodes PDOs
    by object dictionaries. Same text as `meaning()` / `decode()` /
    `describe()`, except:

    - PDOs: with `ods` (pairs of an `ObjectDictionary` and the node-id it
      describes, None for the OD's own, e.g. a DCF's) a frame on a PDO's CAN-ID
      (its COB-ID from 0x1400../0x1800.., $NODEID resolved) reads
      "TPDO1 node 5 name=value, ..." by the mapping (0x1600../0x1A00..);
      see `canopenfd.decode.pdo.pdo_text`. `add_od()` adds one later. The
      SYNC, TIME and EMCY CAN-IDs of those dictionaries (0x1005, 0x1012,
      0x1014) are decoded as such too (before PDOs and the default ids).
    - Node guarding: after a request (remote frame on 0x700 + node-id) the
      node's next one-byte frame there is the reply, also with toggle 0
      (`heartbeat.GuardingTracker` says when not).
    - Classic SDO: while a server is in a block transfer's sub-block phase,
      the sending side's frames are "block segment #N" ("... last" for c=1);
      `sdo.SdoBlockTracker` says how the phases are followed.

    Feed every frame of the bus once, in order, from one thread: each call of
    meaning(), decode() or describe() takes the frame as the next one seen.
    Frames of other kinds decode as `meaning()` does."""

    def __init__(self, ods: Iterable[Tuple[Any, Optional[int]]] = ()) -> None:
        self._state = DecoderState()
        for od, node_id in ods:
            self.add_od(od, node_id)

    def add_od(self, od: Any, node_id: Optional[int] = None) -> int:
        """Decode the PDOs of `od` (an ObjectDictionary) on node node_id
        (default: od.node_id; ValueError when neither is known); the number of
        PDOs it defines. Its SYNC, TIME and EMCY CAN-IDs are taken too."""
        found = self._state.pdos.add_od(od, node_id)      # checks the node-id
        self._state.services.add_od(od, node_id if node_id is not None else od.node_id)
        return len(found)

    def meaning(self, frame: Any) -> str:
        return frame_meaning(frame, self._state)

    def decode(self, frame: Any) -> str:
        return decoded_line(frame, self.meaning(frame))

    def describe(self, frame: Any, width: int = 30) -> str:
        return described_line(frame, self.meaning(frame), width)

    def service(self, frame: Any) -> Classified:
        """(service, node-ids) of the frame, by this decoder's dictionaries
        too (see `classify.frame_service`); does not take the frame as seen."""
        return frame_service(frame, self._state)

    def transfer(self, node_id: int) -> Optional[str]:
        """'block download' / 'block upload' while that server is in a sub-block
        phase, else None."""
        return self._state.sdo_blocks.transfer(node_id)

    def reset(self) -> None:
        """Forget every transfer, guarding request and heartbeat producer seen."""
        self._state.sdo_blocks.reset()
        self._state.guarding.reset()
