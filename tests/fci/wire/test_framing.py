"""The robot's TCP stream cut into frames (fci/wire/framing.py): our robustness contract."""

from __future__ import annotations

import struct

from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.fci.wire.framing import (
    HEADER,
    MAX_MESSAGE_SIZE,
    Frame,
    FrameDecoder,
    FramingError,
)
from franka_sim_gym.fci.wire.protocol import (
    Command,
    SetLoadRequest,
    encode_connect_request,
    encode_message,
    encode_move_request,
    encode_request,
)

# ---------------------------------------------------------------------------
# FrameDecoder (our robustness contract)
# ---------------------------------------------------------------------------

GOOD = [
    encode_connect_request(0, 40000),
    encode_request(Command.kGetRobotModel, 1),
    encode_move_request(2, 2, 4),
    encode_message(SetLoadRequest(0.5, (0.0, 0.0, 0.1), (0.0,) * 9), 3),
]


def _frame_of(message: bytes) -> Frame:
    command, command_id, _ = HEADER.unpack_from(message)
    return Frame(command, command_id, message[12:])


def test_several_frames_in_one_chunk_all_decode_in_order():
    decoder = FrameDecoder()
    assert decoder.feed(b"".join(GOOD)) == [_frame_of(m) for m in GOOD]
    assert decoder.buffered == 0


def test_fragmentation_byte_by_byte_decodes_the_same_frames():
    decoder = FrameDecoder()
    out = []
    for b in b"".join(GOOD):
        out += decoder.feed(bytes([b]))
    assert out == [_frame_of(m) for m in GOOD]


def test_header_only_frame_completes_without_further_bytes():
    decoder = FrameDecoder()
    assert decoder.feed(HEADER.pack(2, 9, 12)) == [Frame(2, 9, b"")]


def test_size_below_header_is_reported_and_only_the_12_header_bytes_skipped():
    decoder = FrameDecoder()
    bad = HEADER.pack(4, 7, 11)
    out = decoder.feed(bad + GOOD[0])
    assert out == [
        FramingError("message size 11 below the 12-byte header", 4, 7),
        _frame_of(GOOD[0]),
    ]


def test_size_zero_then_good_frame_byte_by_byte():
    decoder = FrameDecoder()
    out = []
    for b in HEADER.pack(0, 1, 0) + GOOD[2]:
        out += decoder.feed(bytes([b]))
    assert out == [
        FramingError("message size 0 below the 12-byte header", 0, 1),
        _frame_of(GOOD[2]),
    ]


def test_oversized_message_is_discarded_without_buffering_then_parsing_resumes():
    decoder = FrameDecoder()
    total = 3 * (1 << 20) + 12
    out = decoder.feed(HEADER.pack(1, 6, total))
    assert out == [FramingError(f"message size {total} above the 1 MiB bound", 1, 6)]
    assert decoder.discarding == total - 12
    # Payload that looks like headers must not be parsed.
    junk = (HEADER.pack(0, 0, 16) * ((1 << 16) // 12 + 1))[: 1 << 16]
    remaining = total - 12
    peak = 0
    while remaining:
        chunk = junk[: min(len(junk), remaining)]
        assert decoder.feed(chunk) == []
        remaining -= len(chunk)
        peak = max(peak, decoder.buffered)
        assert decoder.discarding == remaining
    assert peak == 0
    assert decoder.feed(GOOD[1]) == [_frame_of(GOOD[1])]


def test_oversized_payload_and_next_frame_in_one_chunk():
    decoder = FrameDecoder()
    size = MAX_MESSAGE_SIZE + 1
    stream = HEADER.pack(3, 8, size) + bytes(size - 12) + GOOD[3]
    out = decoder.feed(stream)
    assert out == [
        FramingError(f"message size {size} above the 1 MiB bound", 3, 8),
        _frame_of(GOOD[3]),
    ]
    assert decoder.buffered == 0 and decoder.discarding == 0


def test_a_message_of_exactly_the_bound_is_accepted_and_buffered_within_it():
    decoder = FrameDecoder()
    message = encode_request(Command.kGetRobotModel, 4, bytes(MAX_MESSAGE_SIZE - 12))
    assert decoder.feed(message[:-1]) == []
    assert decoder.buffered == MAX_MESSAGE_SIZE - 1
    out = decoder.feed(message[-1:])
    assert out == [Frame(11, 4, bytes(MAX_MESSAGE_SIZE - 12))]
    assert decoder.buffered == 0


def test_buffer_never_exceeds_one_header_plus_bounded_payload_over_3_mib():
    decoder = FrameDecoder()
    # Valid near-bound messages and oversized ones, 3+ MiB in all, fed in 100 kB chunks.
    stream = (
        encode_request(11, 1, bytes(MAX_MESSAGE_SIZE - 12))
        + HEADER.pack(1, 2, MAX_MESSAGE_SIZE + 100)
        + bytes(MAX_MESSAGE_SIZE + 88)
        + encode_request(11, 3, bytes(MAX_MESSAGE_SIZE - 12))
        + GOOD[0]
    )
    assert len(stream) > 3 * (1 << 20)
    results = []
    for i in range(0, len(stream), 100_000):
        results += decoder.feed(stream[i : i + 100_000])
        assert decoder.buffered <= MAX_MESSAGE_SIZE
    assert [type(r).__name__ for r in results] == ["Frame", "FramingError", "Frame", "Frame"]
    assert results[-1] == _frame_of(GOOD[0])


def test_custom_bound_and_header_for_other_framings():
    gripper_header = struct.Struct("<HII")  # §10.1: 10-byte header, u16 command
    decoder = FrameDecoder(max_message_size=64, header=gripper_header)
    out = decoder.feed(gripper_header.pack(1, 5, 10) + gripper_header.pack(2, 6, 65) + bytes(55))
    assert out == [Frame(1, 5, b""), FramingError("message size 65 above the 64-byte bound", 2, 6)]
    assert decoder.feed(gripper_header.pack(0, 1, 9)) == [
        FramingError("message size 9 below the 10-byte header", 0, 1)
    ]


_SMALL = 64
_EVENTS = st.lists(
    st.one_of(
        st.binary(max_size=_SMALL - 12).map(lambda p: ("good", p)),
        st.integers(0, 11).map(lambda s: ("small", s)),
        st.integers(_SMALL + 1, 4 * _SMALL).map(lambda s: ("big", s)),
    ),
    max_size=12,
)


@settings(max_examples=200)
@given(events=_EVENTS, cuts=st.lists(st.integers(0, 2000), max_size=20))
def test_any_chunking_of_good_and_bad_frames_gives_the_same_results(events, cuts):
    stream = b""
    expected: list[Frame | FramingError] = []
    for i, (kind, value) in enumerate(events):
        if kind == "good":
            stream += encode_request(7, i, value)
            expected.append(Frame(7, i, value))
        elif kind == "small":
            stream += HEADER.pack(8, i, value)
            expected.append(FramingError(f"message size {value} below the 12-byte header", 8, i))
        else:
            # The discarded payload looks like headers; none may be parsed.
            stream += HEADER.pack(9, i, value) + (HEADER.pack(0, 0, 12) * value)[: value - 12]
            expected.append(FramingError(f"message size {value} above the 64-byte bound", 9, i))
    decoder = FrameDecoder(max_message_size=_SMALL)
    bounds = sorted({c % (len(stream) + 1) for c in cuts} | {0, len(stream)})
    out = []
    for a, b in zip(bounds, bounds[1:], strict=False):
        out += decoder.feed(stream[a:b])
        assert decoder.buffered <= _SMALL
    assert out == expected
    assert decoder.buffered == 0 and decoder.discarding == 0
