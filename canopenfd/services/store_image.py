"""The parameter image the C stack saves (co_store.c, format version 1), read
and written in Python so other representations of it (the text store) convert
to and from it byte for byte.

Layout (integers little-endian): magic "CoFDpar\\0", version u16 = 1, header
length u16 = 28, OD signature u32, record count u32, payload length u32,
CRC-32 u32 over every byte but itself; then records strictly ascending by key,
each key u32 (index << 8 | sub), type u8 (the CiA 301 data type index),
length u32, value bytes. co_store.c's header comment is the reference; this
module checks the same things so an image it accepts is one the stack loads.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from typing import List, NamedTuple

__all__ = ["ImageError", "ParameterImage", "Record", "build_image", "parse_image"]

MAGIC = b"CoFDpar\x00"
VERSION = 1
HEADER = struct.Struct("<8sHHIIII")     # magic, version, header length, signature,
                                         # count, payload length, CRC
RECORD = struct.Struct("<IBI")          # key, type, length
CRC_OFFSET = 24


class ImageError(ValueError):
    """A byte string that is not a whole version 1 parameter image."""


@dataclass(frozen=True)
class Record:
    index: int
    sub: int
    type: int       # CiA 301 data type index (co_od_type_t)
    data: bytes

    @property
    def key(self) -> int:
        return self.index << 8 | self.sub


class ParameterImage(NamedTuple):
    signature: int          # CRC of the OD layout that wrote it (information only)
    records: List[Record]   # ascending by key, no duplicates


def image_crc(image: bytes) -> int:
    """The CRC-32 of an image: every byte but the CRC field itself."""
    return zlib.crc32(image[CRC_OFFSET + 4:], zlib.crc32(image[:CRC_OFFSET]))


def build_image(image: ParameterImage) -> bytes:
    """The bytes the stack would save for these records (sorted, unique keys)."""
    keys = [record.key for record in image.records]
    if keys != sorted(set(keys)):
        raise ImageError("records must be ascending by key without duplicates")
    payload = b"".join(RECORD.pack(r.key, r.type, len(r.data)) + r.data for r in image.records)
    header = HEADER.pack(MAGIC, VERSION, HEADER.size, image.signature, len(image.records),
                         len(payload), 0)
    unsealed = header + payload
    return unsealed[:CRC_OFFSET] + struct.pack("<I", image_crc(unsealed)) + \
        unsealed[CRC_OFFSET + 4:]


def parse_image(image: bytes) -> ParameterImage:
    """The records of a whole image; ImageError says what is wrong."""
    if len(image) < HEADER.size:
        raise ImageError(f"{len(image)} bytes, shorter than the {HEADER.size}-byte header")
    magic, version, header, signature, count, payload, crc = HEADER.unpack_from(image)
    if magic != MAGIC:
        raise ImageError(f"magic {magic!r}, expected {MAGIC!r}: not a canopenfd image")
    if version != VERSION:
        raise ImageError(f"format version {version}, expected {VERSION}")
    if header < HEADER.size or header > len(image) or payload != len(image) - header:
        raise ImageError(f"header length {header} / payload length {payload} do not match "
                         f"the {len(image)} bytes of the image (truncated?)")
    if image_crc(image) != crc:
        raise ImageError(f"CRC 0x{crc:08X}, the bytes give 0x{image_crc(image):08X}")
    records: List[Record] = []
    pos = header
    for number in range(count):
        if len(image) - pos < RECORD.size:
            raise ImageError(f"record {number + 1} of {count} runs past the end")
        key, type_, length = RECORD.unpack_from(image, pos)
        pos += RECORD.size
        if length > len(image) - pos:
            raise ImageError(f"record {number + 1} of {count} runs past the end")
        if key > 0xFFFFFF or (records and key <= records[-1].key):
            raise ImageError(f"record {number + 1}: key 0x{key:X} not ascending")
        records.append(Record(key >> 8, key & 0xFF, type_, bytes(image[pos:pos + length])))
        pos += length
    if pos != len(image):
        raise ImageError(f"{len(image) - pos} bytes after the last of {count} records")
    return ParameterImage(signature, records)
