"""canopenfd.gateway.ascii309: the CiA 309-3 request parser and the answer
and value formats, as pure functions (no bus, no socket): the grammar, every
data type's text both ways, every error the parser gives, and garbage that
must never raise. The server over TCP: test_gateway_ascii_server.py."""

from __future__ import annotations

import base64
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canopenfd.gateway import ascii309 as proto
from canopenfd.gateway.ascii309 import Reply, Request, TYPES, parse_request


def req(line: str) -> Request:
    parsed = parse_request(line)
    assert isinstance(parsed, Request), parsed
    return parsed


def err(line: str) -> str:
    parsed = parse_request(line)
    assert isinstance(parsed, Reply), parsed
    return parsed.text


# Requests as CANopenNode documents its gateway's syntax (309/CO_gateway_ascii.h,
# "Command syntax" block and its example "[1] 4 read 0x1017 0 i16") and as
# Lely's coctl takes them: what each line parses to.
@pytest.mark.parametrize("line, seq, net, node, command, args", [
    ("[1] 4 read 0x1017 0 i16", 1, None, 4, "read", (0x1017, 0)),
    ("[2] 1 4 r 0x1017 0", 2, 1, 4, "read", (0x1017, 0)),
    ("[3] r 0x1018 1 u32", 3, None, None, "read", (0x1018, 1)),
    ("[4] 4 w 0x1017 0 i16 1000", 4, None, 4, "write", (0x1017, 0)),
    ("[5] 4 start", 5, None, 4, "start", ()),
    ("[6] 0 stop", 6, None, 0, "stop", ()),
    ("[7] 4 preop", 7, None, 4, "preop", ()),
    ("[8] 4 preoperational", 8, None, 4, "preop", ()),
    ("[9] 4 reset node", 9, None, 4, "reset_node", ()),
    ("[10] 4 reset comm", 10, None, 4, "reset_comm", ()),
    ("[11] 2 3 reset communication", 11, 2, 3, "reset_comm", ()),
    ("[12] set network 2", 12, None, None, "set_network", (2,)),
    ("[13] 2 set node 5", 13, 2, None, "set_node", (5,)),
    ("[14] set sdo_timeout 1000", 14, None, None, "set_sdo_timeout", (1000,)),
    ("[15] set sdo_block 1", 15, None, None, "set_sdo_block", (1,)),
    ("[16] info version", 16, None, None, "info_version", ()),
    ("[17] help", 17, None, None, "help", ()),
    ("[18] lss_switch_glob 1", 18, None, None, "lss_switch_glob", (1,)),
    ("[19] 1 lss_switch_sel 0x1A2 0xBEEF01 0x20003 0x80000001", 19, 1, None, "lss_switch_sel",
     (0x1A2, 0xBEEF01, 0x20003, 0x80000001)),
    ("[20] lss_set_node 9", 20, None, None, "lss_set_node", (9,)),
    ("[21] lss_conf_bitrate 0 2", 21, None, None, "lss_conf_bitrate", (0, 2)),
    ("[22] lss_activate_bitrate 100", 22, None, None, "lss_activate_bitrate", (100,)),
    ("[23] lss_store", 23, None, None, "lss_store", ()),
    ("[24] lss_inquire_addr", 24, None, None, "lss_inquire_addr", ()),
    ("[25] lss_inquire_addr 3", 25, None, None, "lss_inquire_addr", (3,)),
    ("[26] lss_get_node", 26, None, None, "lss_get_node", ()),
    ("[27] lss_allnodes 50 10 0", 27, None, None, "lss_allnodes", (50, 10, 0)),
    ("[4294967295] R 0X1017 0 I16   # upper case, a comment\r\n", 0xFFFFFFFF, None, None,
     "read", (0x1017, 0)),
])
def test_request_grammar(line, seq, net, node, command, args):
    parsed = req(line)
    assert (parsed.seq, parsed.net, parsed.node, parsed.command, parsed.args) == \
        (seq, net, node, command, args)


def test_empty_and_comment_lines_get_no_answer():
    assert parse_request("") is None
    assert parse_request("   \r\n") is None
    assert parse_request("# just a comment") is None


# The gateway error codes of CiA 309-3 the parser gives (the others come
# from the server: test_gateway_ascii_server.py::test_error_codes).
@pytest.mark.parametrize("line, answer", [
    ("r 0x1000 0", "[0] ERROR: 101 #Syntax error: a request starts with [sequence]"),
    ("[x] r 0x1000 0", "[0] ERROR: 101 #Syntax error: sequence '[x]' is not 0..4294967295"),
    ("[4294967296] r 0x1000 0", "[0] ERROR: 101 #Syntax error: sequence '[4294967296]' "
                                "is not 0..4294967295"),
    ("[1]", "[1] ERROR: 101 #Syntax error: no command"),
    ("[1] 1 2 3 r 0x1000 0", "[1] ERROR: 101 #Syntax error: more than net and node before "
                             "the command"),
    ("[1] 5 r 0x10000 0", "[1] ERROR: 101 #Syntax error: index '0x10000' is not 0..0xFFFF"),
    ("[1] 5 r 0x1000 256", "[1] ERROR: 101 #Syntax error: sub-index '256' is not 0..0xFF"),
    ("[1] 5 r 0x1000", "[1] ERROR: 101 #Syntax error: r[ead] index sub [type]"),
    ("[1] 5 r 0x1000 0 u12", "[1] ERROR: 101 #Syntax error: unknown data type 'u12'"),
    ("[1] 5 w 0x1000 0 u8", "[1] ERROR: 101 #Syntax error: w[rite] index sub type value"),
    ("[1] 5 w 0x1000 0 u8 256", "[1] ERROR: 101 #Syntax error: 256 is outside u8 (0..255)"),
    ("[1] 5 w 0x1000 0 i8 -129", "[1] ERROR: 101 #Syntax error: -129 is outside i8 "
                                 "(-128..127)"),
    ("[1] 5 w 0x1000 0 b 2", "[1] ERROR: 101 #Syntax error: boolean '2' is not 0 or 1"),
    ('[1] 5 w 0x1000 0 vs "open', "[1] ERROR: 101 #Syntax error: unclosed quote"),
    ("[1] 5 w 0x1000 0 vs two words", "[1] ERROR: 101 #Syntax error: vs takes one value, "
                                      "got 2 tokens (quote a visible string with spaces)"),
    ("[1] 5 w 0x1000 0 d !!!", "[1] ERROR: 101 #Syntax error: d value is not base64 "
                               "(RFC 2045, one line)"),
    ("[1] 5 start now", "[1] ERROR: 101 #Syntax error: start takes no argument"),
    ("[1] 5 reset all", "[1] ERROR: 101 #Syntax error: reset node | reset comm[unication]"),
    ("[1] set node 128", "[1] ERROR: 101 #Syntax error: set node takes 1..127"),
    ("[1] set sdo_block 2", "[1] ERROR: 101 #Syntax error: set sdo_block takes 0..1"),
    ("[1] lss_set_node 128", "[1] ERROR: 101 #Syntax error: lss_set_node: node-id 1..127 or "
                             "255 (unconfigured)"),
    ("[1] lss_allnodes 1 2", "[1] ERROR: 101 #Syntax error: lss_allnodes: [timeout [start "
                             "store [8 scan values]]]"),
    ("[1] fly", "[1] ERROR: 100 #Request not supported: unknown command 'fly'"),
    ("[1] set bitrate 5", "[1] ERROR: 100 #Request not supported: set bitrate"),
    ("[1] info everything", "[1] ERROR: 100 #Request not supported: info version is the info "
                            "request served"),
    ("[1] 200 5 r 0x1000 0", "[1] ERROR: 106 #Unsupported net: net 200"),
    ("[1] 128 r 0x1000 0", "[1] ERROR: 107 #Unsupported node: node 128"),
])
def test_parser_errors(line, answer):
    assert err(line) == answer


def test_error_lines_keep_the_sequence_of_a_broken_line():
    assert err('[77] 5 w 0x2009 0 vs "unclosed').startswith("[77] ERROR: 101")
    assert proto.leading_seq(b"[12345] " + b"x" * 100) == 12345
    assert proto.leading_seq(b"garbage") == 0


def test_answer_formats():
    assert proto.format_ok(7) == "[7] OK"
    assert proto.format_answer(7, "0x03E8") == "[7] 0x03E8"
    assert proto.format_error(7, 103) == "[7] ERROR: 103 #Time-out"
    assert proto.format_abort(7, 0x06020000) == \
        "[7] ERROR: 0x06020000 #object does not exist in the object dictionary"
    assert proto.format_abort(7, 0x12345678) == "[7] ERROR: 0x12345678 #unknown abort code"
    # every code CiA 309-3 lists has its text
    assert sorted(proto.ERROR_TEXT) == [100, 101, 102, 103, 104, 105, 106, 107, 200, 201, 202,
                                        203, 204, 205, 300, 301, 303, 304, 305, 400, 401, 501,
                                        502, 503, 504, 505, 600]


# Every data type: the bytes a written text gives, and the text those bytes read as.
@pytest.mark.parametrize("kind, text, data", [
    ("b", "1", b"\x01"),
    ("b", "0", b"\x00"),
    ("i8", "-128", b"\x80"),
    ("i16", "-1000", struct.pack("<h", -1000)),
    ("i32", "-100000", struct.pack("<i", -100000)),
    ("i64", "-9223372036854775808", struct.pack("<q", -(1 << 63))),
    ("u8", "255", b"\xff"),
    ("u16", "1000", struct.pack("<H", 1000)),
    ("u32", "305419896", struct.pack("<I", 0x12345678)),
    ("u64", "18446744073709551615", b"\xff" * 8),
    ("x8", "0x0A", b"\x0a"),
    ("x16", "0x03E8", struct.pack("<H", 1000)),
    ("x32", "0x12345678", struct.pack("<I", 0x12345678)),
    ("x64", "0x0123456789ABCDEF", struct.pack("<Q", 0x0123456789ABCDEF)),
    ("r32", "1.5", struct.pack("<f", 1.5)),
    ("r32", "0.1", struct.pack("<f", 0.1)),
    ("r64", "-0.25", struct.pack("<d", -0.25)),
    ("r64", "0.1", struct.pack("<d", 0.1)),
    ("t", "43200000 14610", struct.pack("<IH", 43200000, 14610)),
    ("td", "1500 1", struct.pack("<IH", 1500, 1)),
    ("vs", '"canopenfd"', b"canopenfd"),
    ("vs", '"say ""hi"""', b'say "hi"'),
    ("vs", '"a\\\\b\\n\\r\\t\\x01\\xE9"', b"a\\b\n\r\t\x01\xe9"),
    ("vs", '""', b""),
    ("os", "AQIDBAUGBwg=", bytes(range(1, 9))),
    ("us", base64.b64encode("Grüße".encode("utf-16-le")).decode(),
     "Grüße".encode("utf-16-le")),
    ("d", base64.b64encode(bytes(range(256))).decode(), bytes(range(256))),
    ("hex", "01 02 FF", b"\x01\x02\xff"),
])
def test_every_data_type_both_ways(kind, text, data):
    assert proto.format_value(TYPES[kind], data) == text
    written = req(f"[1] 5 w 0x2000 0 {kind} {text}")
    assert written.value == data and written.kind is TYPES[kind]


def test_written_values_in_other_notations():
    assert req("[1] 5 w 0x2000 0 u16 0x3E8").value == struct.pack("<H", 1000)
    assert req("[1] 5 w 0x2000 0 i16 -0x10").value == struct.pack("<h", -16)
    assert req("[1] 5 w 0x2000 0 vs bare").value == b"bare"
    assert req('[1] 5 w 0x2000 0 d ""').value == b""
    assert req("[1] 5 w 0x2000 0 r32 1e-3").value == struct.pack("<f", 1e-3)


def test_values_of_the_wrong_size_print_as_hex_pairs():
    # a server answering 3 bytes for a u32 (CANopenNode prints such data as hex too)
    assert proto.format_value(TYPES["u32"], b"\x01\x02\x03") == "01 02 03"
    assert proto.format_value(TYPES["t"], b"\xff\xff\xff\xff\xff\xff") == \
        "FF FF FF FF FF FF"   # ms beyond a day: not a time of day


def test_visible_strings_with_any_bytes_survive_one_line():
    data = bytes(range(256))
    text = proto.format_value(TYPES["vs"], data)
    assert "\n" not in text and "\r" not in text and text.isascii()
    assert req(f"[1] 5 w 0x2000 0 vs {text}").value == data


@settings(max_examples=400, deadline=None)
@given(st.binary(max_size=300))
def test_garbage_never_raises(data):
    for line in (data, b"[1] " + data, b"[1] 5 w 0x2000 0 vs " + data,
                 b"[1] 5 w 0x2000 0 d " + data):
        parsed = parse_request(line)
        assert parsed is None or isinstance(parsed, (Request, Reply))
        if isinstance(parsed, Reply):
            assert parsed.text.startswith("[") and "\n" not in parsed.text


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(sorted(TYPES)), st.binary(max_size=64))
def test_formatting_never_raises_and_reads_back(kind, data):
    text = proto.format_value(TYPES[kind], data)
    assert "\n" not in text
    # an empty octet string / domain reads as nothing (base64 of no bytes);
    # it is written back as "" (test_written_values_in_other_notations)
    written = text or '""'
    parsed = parse_request(f"[1] 5 w 0x2000 0 {kind} {written}")
    if kind in ("vs", "os", "us", "d") or (kind == "hex" and data) or \
            (TYPES[kind].data_type.size == len(data) and isinstance(parsed, Request)):
        assert isinstance(parsed, Request), parsed
        if kind in ("t", "td"):   # the 4 reserved bits above the 28-bit ms are not kept
            data = data[:3] + bytes([data[3] & 0x0F]) + data[4:]
        assert parsed.value == data
