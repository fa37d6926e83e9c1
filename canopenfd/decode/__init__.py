"""One-line, human-readable text for a CAN frame: NMT, boot-up, heartbeat,
node guarding, SYNC, TIME, EMCY (classic and FD), PDOs, USDO (CAN FD frames on
0x601..0x67F and 0x581..0x5FF) and classic SDO (classic frames on the same
CAN-IDs) decoded, malformed ones marked ('... malformed: why'); anything else
shown raw. Used by the CLI monitor and the demo; pure Python, no runtime
needed.

`decode()` / `describe()` / `meaning()` look at one frame alone: PDOs by the
CiA 301 default CAN-IDs ("TPDO1 node 5 01 02"). A `Decoder` (what the monitor
keeps) also follows what needs earlier frames (SDO block segments, node
guarding replies with toggle 0), and decodes PDOs by the mappings of the
object dictionaries given to it (`Decoder(ods=[(od, node_id)])`).

Modules, bottom up (each imports only the ones above it):

- `raw`: a frame's fields, hex bytes, the raw text and the FD marker
- `nmt`, `heartbeat` (boot-up, heartbeat, node guarding), `usdo`, `sdo`
  (with the block-transfer tracker), `sync`, `time`, `emcy`: one protocol each
- `od_values`: what an object dictionary configures (values, COB-ID bits)
- `pdo` (default CAN-IDs and `PdoMap`), `service_ids` (SYNC/TIME/EMCY ids
  from dictionaries)
- `dispatch`: which protocol a frame belongs to; `meaning`, `decode`, `describe`
- `classify`: the service and node-ids of a frame (the monitor's filters)
- `decoder`: the stateful `Decoder`
"""

from .classify import SERVICE_GROUPS, SERVICES, frame_service, service_names
from .decoder import Decoder
from .dispatch import DESCRIBE_RAW_BYTES, decode, describe, meaning
from .emcy import (EMCY_BASE, EMCY_CLASSIC_LEN, EMCY_CODES, EMCY_FD_LEN, ERROR_REGISTER_BITS,
                   EmcyFields, emcy_code_text, emcy_status_text, emcy_text,
                   error_register_text, parse_emcy)
from .pdo import (DEFAULT_PDO_BASES, DUMMY_TYPES, MappedObject, PdoDefinition, PdoMap,
                  default_pdo, default_pdo_text, format_pdo_value, pdo_text)
from .raw import format_flags, format_raw, hex_bytes
from .sdo import sdo_abort_text
from .service_ids import ServiceIds, service_text
from .sync import SYNC_COUNTER_MAX, SYNC_ID, sync_text
from .time import TIME_ID, TIME_LEN, format_time_of_day, time_text
from .usdo import USDO_COMMANDS, usdo_abort_text, usdo_type_name

__all__ = [
    "Decoder", "decode", "describe", "meaning", "DESCRIBE_RAW_BYTES",
    "format_raw", "format_flags", "hex_bytes",
    "USDO_COMMANDS", "usdo_type_name", "usdo_abort_text", "sdo_abort_text",
    "SYNC_ID", "SYNC_COUNTER_MAX", "sync_text",
    "TIME_ID", "TIME_LEN", "format_time_of_day", "time_text",
    "EMCY_BASE", "EMCY_CLASSIC_LEN", "EMCY_FD_LEN", "EMCY_CODES", "ERROR_REGISTER_BITS",
    "EmcyFields", "parse_emcy", "emcy_text", "emcy_code_text", "error_register_text",
    "emcy_status_text",
    "DEFAULT_PDO_BASES", "DUMMY_TYPES", "default_pdo", "default_pdo_text", "MappedObject",
    "PdoDefinition", "PdoMap", "pdo_text", "format_pdo_value",
    "ServiceIds", "service_text",
    "SERVICES", "SERVICE_GROUPS", "frame_service", "service_names",
]
