"""What the harnesses require of an imported dictionary (shared by them).

An import either raises `OdFileError` (the documented error) or returns a
dictionary that validates without raising, exports to EDS (only a string
holding a line break may refuse, with `OdValueError`, as documented) and
reads back from that export as the same device.
"""

from __future__ import annotations

from _common import Finding, instrumented

with instrumented():
    from canopenfd.od import ObjectDictionary, OdFileError, OdValueError
    from canopenfd.od.eds import eds_from_text, export_dcf, export_eds

__all__ = ["imported", "round_trip", "OdFileError"]


def imported(load, data: bytes):
    """`load(data)`; None when it refused the data with OdFileError."""
    try:
        od = load(data)
    except OdFileError as exc:
        if not str(exc) or not exc.file:
            raise Finding(f"OdFileError without a location: {exc!r}") from exc
        return None
    if not isinstance(od, ObjectDictionary):
        raise Finding(f"the import returned {type(od).__name__}")
    return od


def round_trip(od) -> None:
    """Validate, export to EDS/DCF and read the export back unchanged."""
    problems = od.validate()
    if not isinstance(problems, list):
        raise Finding(f"validate() returned {type(problems).__name__}")
    try:
        text = export_eds(od)
        export_dcf(od)  # the same checks; read back below
    except OdValueError as exc:
        if "line break" not in str(exc):
            raise
        return
    again = _read_back(text, "again.eds", od)
    dcf = _read_back(export_dcf(od), "again.dcf", od)
    if dcf.node_id != od.node_id:
        raise Finding(f"the DCF export reads back node-id {dcf.node_id}, not {od.node_id}")
    if _spaces_around_strings(od):
        return  # documented: an INI line cannot keep them (export_eds)
    differences = again.diff(od)
    if differences:
        raise Finding("the EDS export reads back different: " + "; ".join(differences[:5]))


def _read_back(text, name: str, od):
    try:
        # strict: what the lenient import recovered must export as a clean file
        return eds_from_text(text, name, node_id=od.node_id, mode=od.mode, strict=True)
    except OdFileError as exc:
        raise Finding(f"the export of an imported file cannot be read back: {exc}\n"
                      f"--- export ---\n{text}") from exc


def _spaces_around_strings(od) -> bool:
    """A string value with leading or trailing white space (export_eds says
    it is lost: INI values are stripped)."""
    for var in od.entries():
        for value in (var.default_base, var.value_base):
            if isinstance(value, str) and value != value.strip():
                return True
    return False
