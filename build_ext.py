"""cffi builder of canopenfd._core (API mode, out-of-line).

The cdef is not kept by hand: it is the text between the ``/* cffi:begin */``
and ``/* cffi:end */`` markers of the public headers, so the binding cannot
drift from the C declarations (and in API mode the compiler checks it against
them).

    python3 build_ext.py        # build canopenfd/_core*.so in place (development)
    pip install .               # setuptools runs this through setup.py's cffi_modules
"""
import glob
import os
import re
import shutil
import sys

from cffi import FFI

ROOT = os.path.dirname(os.path.abspath(__file__))

# Headers whose cffi blocks make up the cdef, in dependency order.
CDEF_HEADERS = [
    "csrc/include/canopenfd/co_frame.h",
    "csrc/include/canopenfd/co_line.h",
    "csrc/include/canopenfd/co_nmt.h",
    "csrc/include/canopenfd/co_hb.h",
    "csrc/include/canopenfd/co_od.h",
    "csrc/include/canopenfd/co_store.h",
    "csrc/include/canopenfd/co_usdo.h",
    "csrc/include/canopenfd/co_emcy_codec.h",
    "csrc/include/canopenfd/co_emcy.h",
    "csrc/include/canopenfd/co_pdo.h",
    "csrc/include/canopenfd/co_sync.h",
    "csrc/include/canopenfd/co_time.h",
    "csrc/include/canopenfd/co_guard.h",
    "csrc/include/canopenfd/co_runtime.h",
]
# Public headers: csrc/include/canopenfd (included as "canopenfd/co_x.h"); the
# internal ones sit beside their sources and are found there.
INCLUDE_DIRS = ["csrc/include"]
SOURCE_DIRS = ["csrc/core", "csrc/drivers", "csrc/port/linux"]

_BLOCK = re.compile(r"/\*\s*cffi:begin\s*\*/(.*?)/\*\s*cffi:end\s*\*/", re.S)


def cdef_of(path):
    """The cffi blocks of one header, without preprocessor lines."""
    with open(os.path.join(ROOT, path), encoding="utf-8") as f:
        blocks = _BLOCK.findall(f.read())
    if not blocks:
        raise RuntimeError(f"{path}: no /* cffi:begin */ ... /* cffi:end */ block")
    lines = "\n".join(blocks).splitlines()
    return "\n".join(line for line in lines if not line.lstrip().startswith("#"))


def cdef_text():
    return "\n".join(f"/* from {path} */\n{cdef_of(path)}" for path in CDEF_HEADERS)


def _paths(relative, absolute):
    # setuptools wants paths relative to the project directory (its cwd);
    # ffibuilder.compile() changes directory, so in-place builds use absolute ones.
    return [os.path.join(ROOT, p) if absolute else p for p in relative]


def c_sources():
    found = []
    for directory in SOURCE_DIRS:
        found += sorted(glob.glob(os.path.join(ROOT, directory, "*.c")))
    return [os.path.relpath(p, ROOT) for p in found]


def make_builder(absolute_paths):
    builder = FFI()
    builder.cdef(cdef_text())
    builder.set_source(
        "canopenfd._core",
        "".join(f'#include "canopenfd/{os.path.basename(h)}"\n' for h in CDEF_HEADERS),
        sources=_paths(c_sources(), absolute_paths),
        include_dirs=_paths(INCLUDE_DIRS, absolute_paths),
        # C99 for the core; the Linux files define _GNU_SOURCE themselves.
        extra_compile_args=["-std=c99", "-O2", "-Wall", "-Wextra"],
        libraries=["pthread"],
    )
    return builder


# What setup.py's cffi_modules picks up.
ffibuilder = make_builder(absolute_paths=os.path.abspath(os.getcwd()) != ROOT)


def _in_place_name(built):
    # cffi's C code uses the limited API, and setuptools (pip install -e .)
    # names the file _core.abi3.so: use the same name so the two builds replace
    # each other instead of one shadowing the other.
    if hasattr(sys, "gettotalrefcount"):   # debug interpreter: no limited API
        return os.path.basename(built)
    return "_core.abi3.so"


def build_in_place():
    """Compile into build/cffi and copy the extension next to canopenfd/__init__.py."""
    tmpdir = os.path.join(ROOT, "build", "cffi")
    built = make_builder(absolute_paths=True).compile(tmpdir=tmpdir, verbose="-v" in sys.argv)
    package = os.path.join(ROOT, "canopenfd")
    for stale in glob.glob(os.path.join(package, "_core.*.so")):
        os.remove(stale)
    target = os.path.join(package, _in_place_name(built))
    shutil.copy2(built, target)
    print(f"built {os.path.relpath(target, ROOT)}")


if __name__ == "__main__":
    build_in_place()
