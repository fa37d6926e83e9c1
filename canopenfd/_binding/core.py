"""Loads the compiled C stack; the one import of `canopenfd._core` in the package."""

from typing import TYPE_CHECKING, Any

try:
    from .._core import ffi, lib
except ImportError as exc:  # pragma: no cover - only without a build
    raise ImportError(
        "canopenfd._core (the compiled C stack) is missing: install the package with "
        "'pip install .' (or 'pip install -e .') so build_ext.py compiles it") from exc

__all__ = ["ffi", "lib", "CData"]

if TYPE_CHECKING:
    class CData:
        """A cffi object (cdata: a C struct, array or pointer); opaque above the
        binding. Its fields and items are C's, which cffi knows only at run time
        (from the cdef), so mypy takes them as Any."""

        def __getattr__(self, name: str) -> Any: ...
        def __setattr__(self, name: str, value: Any) -> None: ...
        def __getitem__(self, index: int) -> Any: ...
        def __setitem__(self, index: int, value: Any) -> None: ...
        def __add__(self, offset: int) -> "CData": ...   # pointer arithmetic
else:
    CData = object   # annotations only: cdata objects are cffi's own type
