"""Shared plumbing of the atheris harnesses in this directory.

Each harness defines `check(data: bytes)`, which raises `Finding` (or lets an
unexpected exception escape) when the package misbehaves on `data`, and calls
`main(...)`. Run it:

    python tests/fuzz/py/fuzz_eds.py -max_total_time=60        # fuzz (needs atheris)
    python tests/fuzz/py/fuzz_eds.py crash-1234 dir/           # replay files (no atheris needed)

Without a corpus directory on the command line, the harness fuzzes into
build/pyfuzz/<harness>/corpus, seeded with the test suite's device
description files (tests/data/od, hostile ones included) and the small ones
of seeds/ that fit it.
libFuzzer options (-max_total_time, -runs, -timeout, -artifact_prefix, ...)
pass through unchanged.
"""

from __future__ import annotations

import contextlib
import os
import random
import re
import shutil
import sys
import traceback
from typing import Callable, Iterator, List, Sequence

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
SEEDS = os.path.join(ROOT, "tests", "data", "od")


class Finding(AssertionError):
    """The package did something the harness forbids (not an exception of its own)."""


try:
    import atheris  # type: ignore[import-not-found]
except ImportError:  # replay mode only
    atheris = None


@contextlib.contextmanager
def instrumented() -> Iterator[None]:
    """Imports inside are instrumented for coverage (canopenfd.od and the OD tables)."""
    if atheris is None:
        yield
        return
    with atheris.instrument_imports(include=["canopenfd.od", "canopenfd._binding.od_tables"]):
        yield


def seed_files(suffixes: Sequence[str]) -> List[str]:
    """The test suite's files ending in one of `suffixes` (hostile ones too),
    and the small ones of seeds/ here (quicker to mutate than whole devices)."""
    found = []
    for top in (SEEDS, os.path.join(HERE, "seeds")):
        for folder, _dirs, files in os.walk(top):
            found.extend(os.path.join(folder, name) for name in sorted(files)
                         if name.lower().endswith(tuple(suffixes)))
    return sorted(found)


# Values a text mutation puts where a file holds one (after "key=", inside
# attribute quotes): empty, comments, signs, limits of the widths, bad notations.
_VALUES = [b"", b" ", b";", b"; x", b"#", b"0", b"1", b"-1", b"00", b"08", b"0x", b"0x0",
           b"0xFF", b"0x100", b"0xFFFF", b"0x10000", b"0xFFFFFFFF", b"4294967296", b"-2147483649",
           b"0xFFFFFFFFFFFFFFFF", b"99999999999999999999", b"1" * 90, b"$NODEID",
           b"$NODEID+0xFFFF", b"0x180+$NODEID", b"$NODEID*2", b"nan", b"-inf", b"1e999", b"1.5",
           b"0x2", b"0x7", b"0x8", b"0x9", b"0x0007", b"0x0009", b"0x000F", b"0x0010", b"ro",
           b"rw", b"const", b"rx", b"true", b"1_0", b"\xd9\xa1", b"\xff", b"\xc3", b"&#0;",
           b"&amp;", b"0 1", b"01 02 0", b"\t", b"a\rb"]
_VALUE_RE = re.compile(rb'"([^"\n]*)"|=([^\n"]*)$', re.M)


def structured_mutation(data: bytes, max_size: int, seed: int) -> bytes:
    """Half the time libFuzzer's byte mutations; else a change of the file's
    structure: a line deleted, duplicated or moved, or one value (after '=' or
    in quotes) replaced by one of _VALUES or cut short. Byte mutations seldom
    hit exactly one value of a multi-KiB file, where these bugs live."""
    rng = random.Random(seed)
    if not data or rng.random() < 0.5:
        return atheris.Mutate(data, max_size)
    lines = data.split(b"\n")
    choice = rng.random()
    if choice < 0.1:
        del lines[rng.randrange(len(lines))]
    elif choice < 0.2:
        lines.insert(rng.randrange(len(lines) + 1), rng.choice(lines))
    elif choice < 0.25:
        i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
    else:
        values = list(_VALUE_RE.finditer(data))
        if not values:
            return atheris.Mutate(data, max_size)
        found = rng.choice(values)
        group = 1 if found.group(1) is not None else 2
        start, end = found.span(group)
        old = data[start:end]
        new = rng.choice(_VALUES) if rng.random() < 0.8 or not old else \
            old[:rng.randrange(len(old))]
        return (data[:start] + new + data[end:])[:max_size]
    return b"\n".join(lines)[:max_size]


def _replay(check: Callable[[bytes], None], paths: Sequence[str]) -> int:
    """Run `check` on files (and the files of directories); 1 when one fails."""
    files: List[str] = []
    for path in paths:
        if os.path.isdir(path):
            files.extend(os.path.join(path, n) for n in sorted(os.listdir(path))
                         if os.path.isfile(os.path.join(path, n)))
        else:
            files.append(path)
    failed = 0
    for path in files:
        with open(path, "rb") as handle:
            data = handle.read()
        try:
            check(data)
        except Exception:  # noqa: BLE001 - every escape is the finding reported
            failed += 1
            print(f"FAILED {path}", file=sys.stderr)
            traceback.print_exc()
    print(f"replayed {len(files)} file(s), {failed} failed")
    return 1 if failed else 0


def main(name: str, check: Callable[[bytes], None], suffixes: Sequence[str],
         dictionaries: Sequence[str] = ()) -> None:
    """Fuzz `check` (or replay files without atheris). `suffixes`: which seed
    files fit; `dictionaries`: libFuzzer token files here, unless -dict= is given."""
    args = sys.argv[1:]
    positional = [a for a in args if not a.startswith("-")]
    if atheris is None:
        if not positional:
            sys.exit(f"{name}: atheris is not installed (pip install atheris; wheels exist "
                     f"for Linux x86_64 and CPython 3.9..3.13, elsewhere it needs clang with "
                     f"libFuzzer); without it only replaying files is possible: "
                     f"{name}.py FILE|DIR...")
        sys.exit(_replay(check, positional))
    if not positional:
        corpus = os.path.join(ROOT, "build", "pyfuzz", name, "corpus")
        os.makedirs(corpus, exist_ok=True)
        for path in seed_files(suffixes):
            flat = os.path.relpath(path, ROOT).replace(os.sep, "_")
            target = os.path.join(corpus, "seed-" + flat)
            if not os.path.exists(target):
                shutil.copyfile(path, target)
        args.append(corpus)
    if dictionaries and not any(a.startswith("-dict=") for a in args):
        work = os.path.join(ROOT, "build", "pyfuzz", name)
        os.makedirs(work, exist_ok=True)
        merged = os.path.join(work, "tokens.dict")
        with open(merged, "w", encoding="utf-8") as out:
            for dictionary in dictionaries:
                with open(os.path.join(HERE, dictionary), encoding="utf-8") as source:
                    out.write(source.read())
        args.insert(0, "-dict=" + merged)

    def one_input(data: bytes) -> None:
        check(data)

    atheris.Setup([sys.argv[0]] + args, one_input, custom_mutator=structured_mutation)
    atheris.Fuzz()
