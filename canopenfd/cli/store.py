"""`canopenfd store export|import|seal`: convert a node's saved parameters
between the stack's binary image (a `store=PATH` file) and the retentive text
store (canopenfd.services.store_text), and reseal a text store after a person
edited it. Every output is written atomically (temporary file, fsync,
rename); a damaged input is an error naming the file and line (exit 2) and
writes nothing.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import ConfigurationError
from ..services.atomic_file import replace_file
from ..services.store_image import ImageError, build_image, parse_image
from ..services.store_text import StoreFileError, format_text, parse_text
from .common import EXIT_OK


def add_parsers(subparsers: Any) -> argparse.ArgumentParser:
    """Register `store export|import|seal` on the main parser's subparsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "store", help="convert saved parameters between the binary image and the text store",
        description="Convert a node's saved parameters (0x1010) between the binary image the "
                    "stack writes and the human-readable text store, or reseal a text store "
                    "edited by hand.")
    actions = parser.add_subparsers(dest="store_cmd", metavar="ACTION")
    actions.required = True
    export = actions.add_parser("export", help="binary image -> text store")
    export.add_argument("image", metavar="IMAGE", help="binary parameter image")
    export.add_argument("text", metavar="TEXT", help="text store to write")
    export.set_defaults(func=cmd_export)
    load = actions.add_parser("import", help="text store -> binary image")
    load.add_argument("text", metavar="TEXT", help="text store to read")
    load.add_argument("image", metavar="IMAGE", help="binary parameter image to write")
    load.set_defaults(func=cmd_import)
    seal = actions.add_parser("seal", help="recompute the checksum of an edited text store")
    seal.add_argument("text", metavar="TEXT", help="text store to check and reseal in place")
    seal.set_defaults(func=cmd_seal)
    return parser


def _read(path: str) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError as exc:
        raise ConfigurationError(f"{path}: cannot read: {exc.strerror}") from None


def _write(path: str, data: bytes) -> None:
    try:
        replace_file(path, data)
    except OSError as exc:
        raise ConfigurationError(f"{path}: cannot write: {exc.strerror}") from None


def _done(text: str) -> int:
    print(text, file=sys.stdout, flush=True)
    return EXIT_OK


def cmd_export(args: argparse.Namespace) -> int:
    try:
        image = parse_image(_read(args.image))
        text = format_text(image)
    except ImageError as exc:
        raise StoreFileError(str(exc), args.image) from None
    _write(args.text, text.encode("ascii"))
    return _done(f"{args.image} -> {args.text}: {len(image.records)} entries")


def cmd_import(args: argparse.Namespace) -> int:
    image = parse_text(_read(args.text), args.text)
    _write(args.image, build_image(image))
    return _done(f"{args.text} -> {args.image}: {len(image.records)} entries")


def cmd_seal(args: argparse.Namespace) -> int:
    # every rule but the checksum still applies: a deliberate edit, not any file
    image = parse_text(_read(args.text), args.text, check=False)
    _write(args.text, format_text(image).encode("ascii"))
    return _done(f"{args.text}: sealed, {len(image.records)} entries")
