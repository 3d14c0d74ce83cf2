"""The parser's one error type on random and mutated bytes (hypothesis; slow: not in the mutation layer)."""

from __future__ import annotations

from hw_bridge.test_protocol import COMMAND, FEEDBACK, _reframe
from hypothesis import given, settings
from hypothesis import strategies as st

from smm_hw_bridge import protocol as p


def _check_only_typed_error(data: bytes) -> None:
    try:
        frame = p.decode(data)
    except p.ProtocolError:
        return
    assert p.encode(frame) == bytes(data)  # whatever parses re-encodes to the same bytes


@settings(max_examples=5000, deadline=None)
@given(st.binary(max_size=120))
def test_fuzz_random_bytes_give_only_the_typed_error(data: bytes) -> None:
    _check_only_typed_error(data)


@settings(max_examples=6000, deadline=None)
@given(
    base=st.sampled_from([p.encode(COMMAND), p.encode(FEEDBACK)]),
    edits=st.lists(st.tuples(st.integers(0, 71), st.integers(0, 255)), max_size=4),
    cut=st.integers(0, 80),
    fix_crc=st.booleans(),
)
def test_fuzz_mutated_frames_give_only_the_typed_error(base: bytes, edits, cut: int, fix_crc: bool) -> None:  # type: ignore[no-untyped-def]
    data = bytearray(base)
    for index, value in edits:
        if index < len(data):
            data[index] = value
    mutated = bytes(data[: max(cut, 0)] if cut < len(data) else data)
    if fix_crc and len(mutated) >= 8:
        mutated = _reframe(mutated)
    _check_only_typed_error(mutated)


def _outcome(decoder: object, data: bytes) -> object:
    """The decoded frame, or the reason and text of the typed error."""
    try:
        return decoder(data)  # type: ignore[operator]
    except p.ProtocolError as error:
        return error.reason, str(error)


@settings(max_examples=3000, deadline=None)
@given(
    edits=st.lists(st.tuples(st.integers(0, 71), st.integers(0, 255)), max_size=3),
    fix_crc=st.booleans(),
)
def test_the_feedback_decoder_gives_what_decode_gives(edits: list[tuple[int, int]], fix_crc: bool) -> None:
    """decode_feedback's one-unpack path of 72-byte frames: decode's frame (field for field) or its error."""
    data = bytearray(p.encode(FEEDBACK))
    for index, value in edits:
        data[index] = value
    mutated = _reframe(bytes(data)) if fix_crc else bytes(data)
    expected = _outcome(p.decode, mutated)
    got = _outcome(p.decode_feedback, mutated)
    if isinstance(expected, p.FeedbackFrame):
        assert isinstance(got, p.FeedbackFrame)
        assert [(type(v), v) for v in vars(got).values()] == [(type(v), v) for v in vars(expected).values()]
    else:
        assert got == expected
