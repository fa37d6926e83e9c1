"""CiA 301 data types: sizes, ranges, wire encoding (property tests with hypothesis)."""

from __future__ import annotations

import atexit
import datetime as dt
import math
import shutil
import struct
import tempfile

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.configuration import set_hypothesis_home_dir  # noqa: E402

from canopenfd.errors import ConfigurationError  # noqa: E402
from canopenfd.od import (DataType, OdValueError, TimeDifference, TimeOfDay,  # noqa: E402
                          decode, encode)
from canopenfd.od.datatypes import TIME_EPOCH, check, zero_value  # noqa: E402

INTEGER_TYPES = [t for t in DataType if t.is_integer]
SIZES = {
    DataType.BOOLEAN: 1, DataType.INTEGER8: 1, DataType.INTEGER16: 2, DataType.INTEGER24: 3,
    DataType.INTEGER32: 4, DataType.INTEGER40: 5, DataType.INTEGER48: 6, DataType.INTEGER56: 7,
    DataType.INTEGER64: 8, DataType.UNSIGNED8: 1, DataType.UNSIGNED16: 2,
    DataType.UNSIGNED24: 3, DataType.UNSIGNED32: 4, DataType.UNSIGNED40: 5,
    DataType.UNSIGNED48: 6, DataType.UNSIGNED56: 7, DataType.UNSIGNED64: 8,
    DataType.REAL32: 4, DataType.REAL64: 8, DataType.TIME_OF_DAY: 6,
    DataType.TIME_DIFFERENCE: 6, DataType.VISIBLE_STRING: None, DataType.OCTET_STRING: None,
    DataType.UNICODE_STRING: None, DataType.DOMAIN: None,
}
MS_PER_DAY = 86_400_000

# Nothing written into the working directory (hypothesis keeps an example
# database and a constants cache in ./.hypothesis), and no per-example
# deadline (slow VMs run this suite too).
_HYPOTHESIS_HOME = tempfile.mkdtemp(prefix="canopenfd-hypothesis-")
atexit.register(shutil.rmtree, _HYPOTHESIS_HOME, True)
set_hypothesis_home_dir(_HYPOTHESIS_HOME)
settings.register_profile("canopenfd-od", database=None, deadline=None)
settings.load_profile("canopenfd-od")


def test_indices_match_cia301():
    assert {t.name: int(t) for t in DataType} == {
        "BOOLEAN": 0x01, "INTEGER8": 0x02, "INTEGER16": 0x03, "INTEGER32": 0x04,
        "UNSIGNED8": 0x05, "UNSIGNED16": 0x06, "UNSIGNED32": 0x07, "REAL32": 0x08,
        "VISIBLE_STRING": 0x09, "OCTET_STRING": 0x0A, "UNICODE_STRING": 0x0B,
        "TIME_OF_DAY": 0x0C, "TIME_DIFFERENCE": 0x0D, "DOMAIN": 0x0F, "INTEGER24": 0x10,
        "REAL64": 0x11, "INTEGER40": 0x12, "INTEGER48": 0x13, "INTEGER56": 0x14,
        "INTEGER64": 0x15, "UNSIGNED24": 0x16, "UNSIGNED40": 0x18, "UNSIGNED48": 0x19,
        "UNSIGNED56": 0x1A, "UNSIGNED64": 0x1B}


@pytest.mark.parametrize("dtype", list(DataType))
def test_sizes_and_signedness(dtype):
    assert dtype.size == SIZES[dtype]
    assert dtype.is_variable_length == (SIZES[dtype] is None)
    if dtype.is_integer:
        bits = 8 * dtype.size
        if dtype.name.startswith("INTEGER"):
            assert dtype.signed
            assert (dtype.min, dtype.max) == (-(1 << bits - 1), (1 << bits - 1) - 1)
        else:
            assert not dtype.signed and (dtype.min, dtype.max) == (0, (1 << bits) - 1)


def test_parse_and_errors_are_configuration_errors():
    assert DataType.parse("unsigned16") is DataType.UNSIGNED16
    assert DataType.parse(7) is DataType.UNSIGNED32
    for bad in (0x0E, 0x17, 0x99, "UINT99", 1.5, None):
        with pytest.raises(OdValueError):
            DataType.parse(bad)
    assert issubclass(OdValueError, ConfigurationError)


# ------------------------------------------------------------------ integers
@st.composite
def integer_and_value(draw):
    dtype = draw(st.sampled_from(INTEGER_TYPES))
    return dtype, draw(st.integers(dtype.min, dtype.max))


@given(integer_and_value())
def test_integers_round_trip_over_full_range(case):
    dtype, value = case
    data = encode(dtype, value)
    assert len(data) == dtype.size
    assert data == value.to_bytes(dtype.size, "little", signed=dtype.signed)
    assert decode(dtype, data) == value


@st.composite
def integer_out_of_range(draw):
    dtype = draw(st.sampled_from(INTEGER_TYPES))
    above = draw(st.booleans())
    distance = draw(st.integers(1, 1 << 80))
    return dtype, (dtype.max + distance if above else dtype.min - distance)


@given(integer_out_of_range())
def test_integers_out_of_range_are_refused(case):
    dtype, value = case
    with pytest.raises(OdValueError, match=f"outside {dtype.name} {dtype.min}..{dtype.max}"):
        encode(dtype, value)


@given(st.sampled_from(INTEGER_TYPES), st.binary(min_size=0, max_size=10))
def test_integer_decode_needs_exact_size(dtype, data):
    if len(data) == dtype.size:
        decode(dtype, data)
    else:
        with pytest.raises(OdValueError, match=f"needs {dtype.size} byte"):
            decode(dtype, data)


def test_integer_wire_vectors_and_wrong_python_types():
    assert encode(DataType.UNSIGNED16, 0x1234) == b"\x34\x12"
    assert encode(DataType.INTEGER24, -1) == b"\xff\xff\xff"
    assert encode(DataType.UNSIGNED40, 0x0102030405) == bytes([5, 4, 3, 2, 1])
    assert decode(DataType.INTEGER16, b"\x00\x80") == -32768
    for bad in (1.0, "1", True, b"\x01", None):
        with pytest.raises(OdValueError, match="expects an int"):
            encode(DataType.UNSIGNED8, bad)
    assert str(pytest.raises(OdValueError, encode, DataType.UNSIGNED16, 70000).value) == \
        "70000 outside UNSIGNED16 0..65535"


# ------------------------------------------------------------------ boolean
@given(st.booleans())
def test_boolean_round_trip(value):
    assert encode(DataType.BOOLEAN, value) == (b"\x01" if value else b"\x00")
    assert decode(DataType.BOOLEAN, encode(DataType.BOOLEAN, value)) is value


def test_boolean_accepts_0_1_refuses_others():
    assert encode(DataType.BOOLEAN, 1) == b"\x01"
    for bad in (2, -1, "true", 0.0):
        with pytest.raises(OdValueError):
            encode(DataType.BOOLEAN, bad)
    with pytest.raises(OdValueError, match="0 or 1"):
        decode(DataType.BOOLEAN, b"\x02")


# ------------------------------------------------------------------ reals
def _same_float(a: float, b: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == b and math.copysign(1, a) == math.copysign(1, b)


@given(st.floats(width=32))
def test_real32_round_trip(value):
    data = encode(DataType.REAL32, value)
    assert len(data) == 4
    assert _same_float(decode(DataType.REAL32, data), value)


@given(st.floats())
def test_real64_round_trip(value):
    data = encode(DataType.REAL64, value)
    assert data == struct.pack("<d", value)
    assert _same_float(decode(DataType.REAL64, data), value)


@given(st.floats(min_value=3.5e38, allow_infinity=False))
def test_real32_out_of_range_refused(value):
    with pytest.raises(OdValueError, match="outside REAL32"):
        encode(DataType.REAL32, value)
    with pytest.raises(OdValueError, match="outside REAL32"):
        encode(DataType.REAL32, -value)


def test_real32_values_are_stored_rounded():
    assert check(DataType.REAL32, 0.1) == struct.unpack("<f", struct.pack("<f", 0.1))[0]
    assert check(DataType.REAL64, 0.1) == 0.1
    with pytest.raises(OdValueError, match="expects a float"):
        encode(DataType.REAL64, "1.0")


# ------------------------------------------------------------------ strings
VISIBLE = st.text(alphabet=st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=300)


@given(VISIBLE)
def test_visible_string_round_trip(text):
    assert encode(DataType.VISIBLE_STRING, text) == text.encode("ascii")
    assert decode(DataType.VISIBLE_STRING, encode(DataType.VISIBLE_STRING, text)) == text


@given(VISIBLE, st.characters().filter(lambda c: not 0x20 <= ord(c) <= 0x7E), VISIBLE)
def test_visible_string_refuses_invisible_characters(head, bad, tail):
    with pytest.raises(OdValueError, match="VISIBLE_STRING allows only visible ASCII"):
        encode(DataType.VISIBLE_STRING, head + bad + tail)


def test_visible_string_decode_is_lenient():
    assert decode(DataType.VISIBLE_STRING, b"abc\x00\x00") == "abc"
    assert decode(DataType.VISIBLE_STRING, b"Ger\xe4t") == "Gerät"  # Latin-1 from a device


UNICODE = st.text(alphabet=st.characters(blacklist_categories=("Cs",), min_codepoint=1),
                  max_size=200)


@given(UNICODE)
def test_unicode_string_round_trip(text):
    data = encode(DataType.UNICODE_STRING, text)
    assert data == text.encode("utf-16-le")
    assert decode(DataType.UNICODE_STRING, data) == text


def test_unicode_string_errors():
    with pytest.raises(OdValueError, match="cannot encode"):
        encode(DataType.UNICODE_STRING, "\ud800")
    with pytest.raises(OdValueError, match="even number"):
        decode(DataType.UNICODE_STRING, b"a\x00b")
    assert decode(DataType.UNICODE_STRING, "hi".encode("utf-16-le") + b"\x00\x00") == "hi"


@given(st.sampled_from([DataType.OCTET_STRING, DataType.DOMAIN]), st.binary(max_size=500))
def test_octets_round_trip(dtype, data):
    assert encode(dtype, data) == data
    assert encode(dtype, bytearray(data)) == data
    assert decode(dtype, data) == data


def test_octets_refuse_text():
    with pytest.raises(OdValueError, match="expects bytes"):
        encode(DataType.OCTET_STRING, "0102")


# ------------------------------------------------------------------ times
TIMES_OF_DAY = st.builds(TimeOfDay, ms=st.integers(0, MS_PER_DAY - 1), days=st.integers(0, 0xFFFF))
TIME_DIFFERENCES = st.builds(TimeDifference, ms=st.integers(0, (1 << 28) - 1),
                             days=st.integers(0, 0xFFFF))


@given(TIMES_OF_DAY)
def test_time_of_day_round_trip(value):
    data = encode(DataType.TIME_OF_DAY, value)
    assert len(data) == 6
    assert decode(DataType.TIME_OF_DAY, data) == value


@given(TIME_DIFFERENCES)
def test_time_difference_round_trip(value):
    assert decode(DataType.TIME_DIFFERENCE, encode(DataType.TIME_DIFFERENCE, value)) == value


def test_time_of_day_vector_from_protocol_notes():
    # §6.8: 2024-01-01 12:34:56.789 -> 95 2C B3 02 12 39
    value = TimeOfDay.from_datetime(dt.datetime(2024, 1, 1, 12, 34, 56, 789000))
    assert (value.ms, value.days) == (45296789, 14610)
    assert encode(DataType.TIME_OF_DAY, value) == bytes.fromhex("952CB3021239")
    assert decode(DataType.TIME_OF_DAY, bytes.fromhex("952CB3F21239")) == value  # reserved bits


@given(st.datetimes(min_value=dt.datetime(1984, 1, 1),
                    max_value=dt.datetime(1984, 1, 1) + dt.timedelta(days=0xFFFF, hours=23)))
def test_time_of_day_datetime_helpers(when):
    value = TimeOfDay.from_datetime(when)
    back = value.to_datetime()
    assert back.tzinfo is not None
    assert back.replace(tzinfo=None) == when.replace(microsecond=when.microsecond // 1000 * 1000)


@given(st.timedeltas(min_value=dt.timedelta(0), max_value=dt.timedelta(days=0xFFFF, hours=23)))
def test_time_difference_timedelta_helpers(delta):
    value = TimeDifference.from_timedelta(delta)
    assert value.to_timedelta() == delta - dt.timedelta(microseconds=delta.microseconds % 1000)


def test_time_errors():
    with pytest.raises(OdValueError, match="ms 86400000 outside"):
        TimeOfDay(MS_PER_DAY, 0)
    with pytest.raises(OdValueError, match="days 65536 outside"):
        TimeDifference(0, 65536)
    with pytest.raises(OdValueError, match="before 1984"):
        TimeOfDay.from_datetime(dt.datetime(1983, 12, 31))
    with pytest.raises(OdValueError, match="negative"):
        TimeDifference.from_timedelta(dt.timedelta(seconds=-1))
    with pytest.raises(OdValueError, match="is not a time of day"):
        decode(DataType.TIME_OF_DAY, (MS_PER_DAY).to_bytes(4, "little") + b"\x00\x00")
    with pytest.raises(OdValueError, match="TIME_OF_DAY expects"):
        encode(DataType.TIME_OF_DAY, TimeDifference(0, 0))
    assert encode(DataType.TIME_DIFFERENCE, dt.timedelta(days=1, milliseconds=5)) == \
        encode(DataType.TIME_DIFFERENCE, TimeDifference(5, 1))
    assert TimeOfDay(0, 0).to_datetime() == TIME_EPOCH


@settings(max_examples=50)
@given(st.sampled_from(list(DataType)))
def test_zero_value_encodes(dtype):
    data = encode(dtype, zero_value(dtype))
    assert len(data) == (dtype.size or 0)


def test_real32_text_is_the_shortest_that_reads_back() -> None:
    import math
    import struct

    from canopenfd.od.datatypes import real32_text

    for value in (0.1, 1.5, -3.25, 1e-30, 1.2345678e20, 16777217.0, 0.0):
        single = struct.unpack("<f", struct.pack("<f", value))[0]
        text = real32_text(single)
        assert struct.pack("<f", float(text)) == struct.pack("<f", single)
        digits = len(text.lstrip("-").split("e")[0].replace(".", "").lstrip("0")) or 1
        if digits > 1:      # one digit fewer does not read back
            fewer = f"{single:.{digits - 1}g}"
            assert struct.pack("<f", float(fewer)) != struct.pack("<f", single), (text, fewer)
    assert real32_text(struct.unpack("<f", struct.pack("<f", 0.1))[0]) == "0.1"
    assert real32_text(math.inf) == "inf" and real32_text(math.nan) == "nan"
