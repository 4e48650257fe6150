"""Framing of the robot's TCP stream (docs/wire-protocol.md §2): a header per message,
cut incrementally from the byte stream with bounded memory.

Shared by the robot's command port (1337) and the gripper's (1338); ``protocol``
re-exports these names.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

# §2.1 CommandHeader: command u32, command_id u32, size u32 (total, header included).
HEADER = struct.Struct("<III")
# Our bound on one message read from the wire (the largest real one is the
# ~15 kB GetRobotModel reply; requests are at most 428 bytes).
MAX_MESSAGE_SIZE = 1 << 20


@dataclass(frozen=True)
class Frame:
    """One complete message: header fields and the payload after the header."""

    command: int
    command_id: int
    payload: bytes


@dataclass(frozen=True)
class FramingError:
    """A header the decoder skipped; ``reason`` is meant for the log."""

    reason: str
    command: int
    command_id: int


def _bound_text(size: int) -> str:
    return f"{size >> 20} MiB" if size % (1 << 20) == 0 else f"{size}-byte"


class FrameDecoder:
    """Cut a TCP byte stream into frames, holding at most one header + one bounded payload.

    * ``size`` < header size: a ``FramingError``; the header bytes are skipped and
      parsing resumes right after them.
    * ``size`` > ``max_message_size``: a ``FramingError``; the declared payload is
      discarded as it arrives (only a counter is kept), then parsing resumes.

    ``header`` is any struct unpacking to (command, command_id, size) with size
    counting the header itself (the robot's ``HEADER`` by default).
    """

    def __init__(
        self, max_message_size: int = MAX_MESSAGE_SIZE, header: struct.Struct = HEADER
    ) -> None:
        if max_message_size < header.size:
            raise ValueError(f"max_message_size {max_message_size} below the header size")
        self._header = header
        self._max = max_message_size
        self._buf = bytearray()
        self._size: int | None = None  # total size of the message whose header is in _buf
        self._discard = 0  # payload bytes of an oversized message still to drop

    @property
    def buffered(self) -> int:
        """Bytes currently held (header + partial payload)."""
        return len(self._buf)

    @property
    def discarding(self) -> int:
        """Bytes of an oversized message still to be dropped."""
        return self._discard

    def feed(self, data: bytes) -> list[Frame | FramingError]:
        """Consume ``data``; return the frames and framing errors it completed, in order."""
        out: list[Frame | FramingError] = []
        view = memoryview(data).cast("B")
        pos, end = 0, len(view)
        hsize = self._header.size
        while True:
            if self._discard:
                n = min(self._discard, end - pos)
                pos += n
                self._discard -= n
                if self._discard:
                    break
            need = hsize if self._size is None else self._size
            take = min(need - len(self._buf), end - pos)
            if take > 0:
                self._buf += view[pos : pos + take]
                pos += take
            if len(self._buf) < need:
                break
            command, command_id, size = self._header.unpack_from(self._buf)
            if self._size is None:
                if size < hsize:
                    reason = f"message size {size} below the {hsize}-byte header"
                elif size > self._max:
                    reason = f"message size {size} above the {_bound_text(self._max)} bound"
                    self._discard = size - hsize
                else:
                    self._size = size  # go round again to collect the payload
                    continue
                out.append(FramingError(reason, command, command_id))
                self._buf.clear()
                continue
            out.append(Frame(command, command_id, bytes(self._buf[hsize:])))
            self._buf.clear()
            self._size = None
        return out
