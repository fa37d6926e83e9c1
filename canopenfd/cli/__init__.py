"""The `canopenfd` command: demo, nmt, monitor, device, od, and the transfer
commands read, write, download, upload (USDO on fd lines, SDO on classic ones).

Errors a user can fix (no such interface, wrong MTU, bad node-id) print one
line to stderr and exit with status 2, never a traceback.

`main(argv, network=...)` runs a command on a given Network (its lines stay
open afterwards) instead of one of its own: an in-process bus ('mem:NAME')
belongs to one Network, so tests and embedding programs reach the nodes they
run themselves this way.

Modules: `entry` (the parser and `main`), one per command group (`demo`,
`nmt`, `monitor`, `device`, `od`, `transfer` for read/write/download/upload),
each registering its subcommands with `add_parsers(subparsers)`, and
`common`, what they share. No command module imports another one.
"""

from .entry import build_parser, main

__all__ = ["main", "build_parser"]
