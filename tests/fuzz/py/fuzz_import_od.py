"""atheris harness: what `create_local_node(od=FILE)` / `add_node(od=FILE)` and
the CLI's `od show FILE` do with a file: `import_od` picks the reader by
content (an unnamed stream: XML or INI), then the dictionary is turned into
the C stack's entry definitions (canopenfd._binding.od_tables), as a local
node's boot does.

Fails on any exception but OdFileError from the import, on a dictionary
that does not validate/export/read back (_checks.py), and on any exception
while building the C definitions of an imported dictionary.
Run: python tests/fuzz/py/fuzz_import_od.py -max_total_time=60   (README-py.md)
"""

import io
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from _checks import imported, round_trip  # noqa: E402
from _common import instrumented, main  # noqa: E402

with instrumented():
    from canopenfd._binding.od_tables import definitions
    from canopenfd.od import import_od


def load_stream(data: bytes):
    return import_od(io.BytesIO(data))


def check(data: bytes) -> None:
    od = imported(load_stream, data)
    if od is None:
        return
    round_trip(od)
    node_id = od.node_id or (len(data) % 127 + 1)
    _defs, count, _keep = definitions(od, node_id)
    assert count == len(list(od.entries()))


if __name__ == "__main__":
    main("fuzz_import_od", check, (".eds", ".dcf", ".xdd", ".xdc"), ("eds.dict", "xdd.dict"))
