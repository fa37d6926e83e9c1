"""cffi builder of canopenfd._core (API mode, out-of-line).

The cdef is not kept by hand: it is the text between the ``/* cffi:begin */``
and ``/* cffi:end */`` markers of the public headers, so the binding cannot
drift from the C declarations (and in API mode the compiler checks it against
them).

    python3 build_ext.py        # build canopenfd/_core*.so in place (development)
    pip install .               # setuptools runs this through setup.py's cffi_modules
    python3 build_ext.py --sources win32   # the C files a platform's build compiles

The C sources are chosen per platform (c_sources): the portable core, membus
and runtime everywhere; SocketCAN, the epoll waiter and the POSIX OS layer on
Linux; the POSIX OS layer on macOS; the Windows OS layer on Windows. cffi is
imported only to build, so listing the sources needs nothing installed.
"""
import glob
import os
import re
import shutil
import sys

ROOT = os.path.dirname(os.path.abspath(__file__))

# Headers whose cffi blocks make up the cdef, in dependency order.
CDEF_HEADERS = [
    "csrc/include/canopenfd/co_frame.h",
    "csrc/include/canopenfd/co_line.h",
    "csrc/include/canopenfd/co_nmt.h",
    "csrc/include/canopenfd/co_hb.h",
    "csrc/include/canopenfd/co_led.h",
    "csrc/include/canopenfd/co_od.h",
    "csrc/include/canopenfd/co_store.h",
    "csrc/include/canopenfd/co_usdo.h",
    "csrc/include/canopenfd/co_emcy_codec.h",
    "csrc/include/canopenfd/co_emcy.h",
    "csrc/include/canopenfd/co_errors.h",
    "csrc/include/canopenfd/co_pdo.h",
    "csrc/include/canopenfd/co_mpdo.h",
    "csrc/include/canopenfd/co_sync.h",
    "csrc/include/canopenfd/co_time.h",
    "csrc/include/canopenfd/co_guard.h",
    "csrc/include/canopenfd/co_lss.h",
    "csrc/include/canopenfd/co_lss_master.h",
    "csrc/include/canopenfd/co_sdo_server.h",
    "csrc/include/canopenfd/co_usdo_server.h",
    "csrc/include/canopenfd/co_usdo_client.h",
    "csrc/include/canopenfd/co_boot.h",
    "csrc/include/canopenfd/co_manager.h",
    "csrc/include/canopenfd/co_sleep.h",
    "csrc/include/canopenfd/co_flyma.h",
    "csrc/include/canopenfd/co_srdo.h",
    "csrc/include/canopenfd/co_gfc.h",
    "csrc/include/canopenfd/co_gateway.h",
    "csrc/include/canopenfd/co_cia401.h",
    "csrc/include/canopenfd/co_cia401_od.h",
    "csrc/include/canopenfd/co_redundancy.h",
    "csrc/include/canopenfd/co_runtime.h",
]
# Public headers: csrc/include/canopenfd (included as "canopenfd/co_x.h"); the
# internal ones sit beside their sources, and the runtime's (co_rt_internal.h,
# co_rt_os.h) are also reached from its per-OS directories.
INCLUDE_DIRS = ["csrc/include", "csrc/port/runtime"]
# Directories (every .c in them) or files, compiled on every platform ...
PORTABLE_SOURCES = ["csrc/core", "csrc/drivers/co_membus.c", "csrc/port/runtime",
                    "csrc/port/store"]
# ... and per platform: SocketCAN and the epoll waiter exist on Linux only.
PLATFORM_SOURCES = {
    "linux": ["csrc/drivers/co_socketcan.c", "csrc/port/linux", "csrc/port/posix"],
    "darwin": ["csrc/port/posix"],
    "win32": ["csrc/port/windows"],
}

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


def platform_family(platform=None):
    """linux, darwin or win32 (any other POSIX system builds like macOS)."""
    platform = platform or sys.platform
    if platform.startswith("linux"):
        return "linux"
    if platform in ("win32", "cygwin"):
        return "win32"
    return "darwin"


def c_sources(platform=None):
    """The C files the extension compiles on a platform (sys.platform by default)."""
    found = []
    for entry in PORTABLE_SOURCES + PLATFORM_SOURCES[platform_family(platform)]:
        path = os.path.join(ROOT, entry)
        found += [path] if entry.endswith(".c") else sorted(glob.glob(os.path.join(path, "*.c")))
    return [os.path.relpath(p, ROOT).replace(os.sep, "/") for p in found]


def compile_args(platform=None):
    if platform_family(platform) == "win32":
        # MSVC: C11 (designated initializers, compound literals, inline); the
        # gcc flags below mean nothing to it.
        return ["/std:c11", "/O2"]
    # C99 for the core; the Linux-only files define _GNU_SOURCE themselves.
    return ["-std=c99", "-O2", "-Wall", "-Wextra"]


def libraries(platform=None):
    # Windows: the OS layer needs only kernel32, which MSVC links anyway.
    return [] if platform_family(platform) == "win32" else ["pthread"]


def make_builder(absolute_paths):
    from cffi import FFI   # only to build: listing the sources needs no cffi

    builder = FFI()
    builder.cdef(cdef_text())
    builder.set_source(
        "canopenfd._core",
        "".join(f'#include "canopenfd/{os.path.basename(h)}"\n' for h in CDEF_HEADERS),
        sources=_paths(c_sources(), absolute_paths),
        include_dirs=_paths(INCLUDE_DIRS, absolute_paths),
        extra_compile_args=compile_args(),
        libraries=libraries(),
    )
    return builder


def ffibuilder():
    """What setup.py's cffi_modules calls (cffi accepts a function)."""
    return make_builder(absolute_paths=os.path.abspath(os.getcwd()) != ROOT)


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
    if len(sys.argv) == 3 and sys.argv[1] == "--sources":
        print("\n".join(c_sources(sys.argv[2])))
    else:
        build_in_place()
