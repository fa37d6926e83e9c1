"""The object dictionary: data model, CiA 301 data types, and the device
description files (EDS/DCF per CiA 306, XDD/XDC per CiA 311 / CiA 1311).

Pure Python, standard library only; the C object dictionary is fed from
`ObjectDictionary.entries()` later::

    from canopenfd.od import import_od, demo_od

    od = import_od("drive.eds", node_id=5)
    od[0x1017].default                    # also od["Producer heartbeat time"]
    od["0x1018:1"].name                   # 'Vendor-ID'
    for problem in od.validate():
        print(problem)
"""

from __future__ import annotations

import logging
from typing import Optional

from .builders import add_manager_requests, add_node_array, add_stamp
from .datatypes import DataType, TimeDifference, TimeOfDay, decode, encode
from .demo import demo_od
from .eds import eds_from_text, export_dcf, export_eds, import_eds
from .errors import OdError, OdFileError, OdStateError, OdValueError
from .fileio import MAX_FILE_SIZE, Source, detect_format, read_source
from .model import ODArray, ODRecord, ODVariable, ObjectDictionary, ObjectType, format_index
from .validate import Problem
from .xdd import import_xdd, xdd_from_text

_log = logging.getLogger(__name__)

__all__ = [
    "DataType", "TimeOfDay", "TimeDifference", "encode", "decode",
    "ObjectDictionary", "ODVariable", "ODRecord", "ODArray", "ObjectType", "format_index",
    "Problem", "OdError", "OdValueError", "OdFileError", "OdStateError",
    "import_od", "import_eds", "import_xdd", "export_eds", "export_dcf", "demo_od",
    "MAX_FILE_SIZE", "add_node_array", "add_stamp", "add_manager_requests",
]


def import_od(source: Source, node_id: Optional[int] = None,
              mode: Optional[str] = None, strict: bool = False) -> ObjectDictionary:
    """An ObjectDictionary from an EDS, DCF, XDD or XDC file (path or open
    file): the reader is chosen by extension, else by content (XML or INI).

    Lenient by default: slips whose intent is clear (a wrong object count, a
    manufacturer data type, a default that does not parse, ...) are recovered
    and each is listed in ``od.load_warnings`` (file:line, problem, what was
    done instead; severity "error"), and logged as a warning.
    ``strict=True`` raises `OdFileError` at the first such deviation."""
    data, name = read_source(source)
    if detect_format(name, data) == "eds":
        od = eds_from_text(data, name, node_id, mode, strict)
    else:
        od = xdd_from_text(data, name, node_id, mode, strict)
    recovered = [problem for problem in od.load_warnings if problem.is_error]
    for problem in recovered:
        _log.warning("%s: %s", problem.where, problem.message)
    return od
