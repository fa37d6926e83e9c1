"""The seed 004 message codec under generated input: requests survive any
split into chunks, any bytes at all are decoded without an exception (every
frame accepted or refused and counted, the buffer bounded), and the host's
decoder takes answers and indications apart."""

from __future__ import annotations

from typing import List, Tuple, Union

from hypothesis import given, settings
from hypothesis import strategies as st

from canopenfd.processimage import codec

_FIXED = {codec.GET_ID: 0, codec.GET_STATUS: 0, codec.INIT_CANOPEN: 2, codec.READ_DATA: 2}


@st.composite
def requests(draw: st.DrawFn) -> codec.Request:
    code = draw(st.sampled_from(sorted(codec.REQUEST_PARAMS)))
    if code == codec.WRITE_DATA:
        data = draw(st.binary(max_size=255))
        params = bytes((draw(st.integers(0, 255)), len(data))) + data
    else:
        params = draw(st.binary(min_size=_FIXED[code], max_size=_FIXED[code]))
    return codec.Request(code, params)


def _chunks(data: bytes, cuts: List[int]) -> List[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts})
    return [data[a:b] for a, b in zip([0, *points], [*points, len(data)])]


@settings(max_examples=300, deadline=None)
@given(st.lists(requests(), max_size=8), st.lists(st.integers(0, 4000), max_size=12))
def test_requests_survive_any_chunking(reqs: List[codec.Request], cuts: List[int]) -> None:
    wire = b"".join(codec.encode_request(r.code, r.params) for r in reqs)
    decoder = codec.RequestDecoder()
    out: List[Union[codec.Request, codec.BadFrame]] = []
    for chunk in _chunks(wire, cuts):
        out += decoder.feed(chunk)
    assert out == reqs
    assert not decoder.pending and decoder.accepted == len(reqs)


@settings(max_examples=500, deadline=None)
@given(st.lists(st.binary(max_size=40), max_size=10))
def test_any_bytes_are_decoded_or_refused(chunks: List[bytes]) -> None:
    decoder = codec.RequestDecoder()
    out: List[Union[codec.Request, codec.BadFrame]] = []
    for chunk in chunks:
        out += decoder.feed(chunk)
        assert decoder.buffered <= 1 + 2 + 255 + 1     # never more than one frame waits
    expired = decoder.expire()
    out += [expired] if expired else []
    assert decoder.accepted + sum(decoder.refused.values()) == len(out)
    for item in out:
        if isinstance(item, codec.Request):
            expected = _FIXED.get(item.code)
            if expected is None:
                assert len(item.params) == 2 + item.params[1]
            else:
                assert len(item.params) == expected
        else:
            assert codec.nak_for(item.code) in (b"!", b"\x00!")


def _answer_bytes(code: int, ok: bool, data: bytes) -> Tuple[bytes, codec.Answer]:
    if code in (codec.READ_DATA, codec.WRITE_DATA):
        if not ok or (code == codec.READ_DATA and not data):
            return b"\x00!", codec.Answer(code, False, b"", 0)
        count = len(data)
        body = data if code == codec.READ_DATA else b""
        return bytes((count,)) + body + b".", codec.Answer(code, True, body, count)
    if not ok:
        return b"!", codec.Answer(code, False, b"")
    size = {codec.GET_ID: 4, codec.GET_STATUS: 1, codec.INIT_CANOPEN: 0}[code]
    body = data[:size].ljust(size, b"\x00")
    if code == codec.GET_STATUS:
        body = bytes((body[0] & 0x1F,))     # bits 5-7 reserved, 0
    return body + b".", codec.Answer(code, True, body)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(sorted(codec.REQUEST_PARAMS)), st.booleans(),
                          st.binary(min_size=1, max_size=60),
                          st.lists(st.tuples(st.sampled_from(sorted(codec.INDICATION_PARAMS)),
                                             st.binary(min_size=2, max_size=2)), max_size=3)),
                max_size=6))
def test_host_decoder_takes_answers_and_indications_apart(exchanges) -> None:
    decoder = codec.TaskDecoder()
    for code, ok, data, indications in exchanges:
        wire, answer = _answer_bytes(code, ok, data)
        items, answered = decoder.feed(wire, code)
        assert answered and items == [answer]
        between = b"".join(codec.encode_indication(c, p[:codec.INDICATION_PARAMS[c]])
                           for c, p in indications)
        items, answered = decoder.feed(between, None)
        assert not answered
        assert items == [codec.Indication(c, p[:codec.INDICATION_PARAMS[c]])
                         for c, p in indications]
    assert decoder.dropped == 0


def test_an_indication_crossing_a_read_that_looks_like_one() -> None:
    """A read of 100 bytes answers with count 64h = 'd'; an NMTChange sent
    before the request came in is still told apart from it."""
    decoder = codec.TaskDecoder()
    data = bytes(range(100))
    items, answered = decoder.feed(b"n\x05." + b"d" + data + b".", codec.READ_DATA)
    assert answered
    assert items == [codec.Indication(codec.NMT_CHANGE, b"\x05"),
                     codec.Answer(codec.READ_DATA, True, data, 100)]
    items, answered = decoder.feed(b"d" + data + b".", codec.READ_DATA)
    assert answered and items == [codec.Answer(codec.READ_DATA, True, data, 100)]
