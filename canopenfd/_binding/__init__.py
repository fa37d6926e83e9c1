"""The binding: the only Python that touches the compiled C stack (`canopenfd._core`).

Everything above it (services, nodes, lines, the CLI) sees Python values,
enums and exceptions, never cffi objects:

- `core`: loads `canopenfd._core` (`ffi`, `lib`) with a helpful message when it is missing
- `constants`: the C enums and constants as Python `IntEnum`s, built from `lib`
- `runtime`: `Runtime`, one C runtime (thread, mailbox, event queue, lines)
- `context`: the narrow line context services get (`LineContext`) and its runtime
  implementation with the event table
- `hostbus`: the python-can bridge threads of host-driver lines
- `od_tables`: an `ObjectDictionary` turned into the C core's entry definitions
- `transfers`: client transfer requests as the C runtime takes them
"""
