"""What an object dictionary configures for a node, as the decoders need it:
an entry's value ($NODEID resolved) and the bits of a COB-ID. Shared by the
PDO mappings (`pdo`) and the SYNC/TIME/EMCY CAN-IDs (`service_ids`)."""

from __future__ import annotations

from typing import Any, Optional

COB_INVALID = 1 << 31
COB_EXT = 1 << 29
COB_11_BITS = 0x7FF
COB_29_BITS = 0x1FFFFFFF


def configured_value(var: Any, node_id: int) -> Any:
    """An entry's value on node node_id: the DCF/XDC value, else the default,
    $NODEID resolved."""
    if var is None:
        return None
    if var.value_base is not None:
        base, relative = var.value_base, var.value_relative_to_node_id
    else:
        base, relative = var.default_base, var.relative_to_node_id
    if base is None:
        return None
    return base + node_id if relative else base


def configured_int(od: Any, index: int, sub: int, node_id: int) -> Optional[int]:
    value = configured_value(od.get_variable(index, sub), node_id)
    return value if isinstance(value, int) and not isinstance(value, bool) else None

