"""Loads the compiled C stack; the one import of `canopenfd._core` in the package."""

try:
    from .._core import ffi, lib
except ImportError as exc:  # pragma: no cover - only without a build
    raise ImportError(
        "canopenfd._core (the compiled C stack) is missing: install the package with "
        "'pip install .' (or 'pip install -e .') so build_ext.py compiles it") from exc

__all__ = ["ffi", "lib", "CData"]

#: A cffi object (cdata: a C struct, array or pointer); opaque above the binding.
CData = object
