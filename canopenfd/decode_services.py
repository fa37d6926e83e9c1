"""Compatibility: the service decoders (SYNC, TIME, EMCY, PDO) moved into the
`canopenfd.decode` package. `canopenfd.emcy` still imports its EMCY texts
from here; once it imports them from `canopenfd.decode`, this module can go."""

from .decode.emcy import emcy_code_text, emcy_status_text, error_register_text

__all__ = ["emcy_code_text", "emcy_status_text", "error_register_text"]
