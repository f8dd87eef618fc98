"""An animated GIF written frame by frame, so a long preview holds one frame in memory, not all.

Pillow's own multi-frame writer keeps every frame until it writes the file (a 5-minute preview took
5 GB). Here each frame is encoded on its own by Pillow (one public ``Image.save``), cropped to what
changed since the frame before, and its image block moved into the stream with its palette as a
local colour table. Frames identical to the one before lengthen it instead (as Pillow does).
"""

from __future__ import annotations

import io
import struct
from typing import BinaryIO, Iterable

_LOOP_FOREVER = b"!\xff\x0bNETSCAPE2.0\x03\x01\x00\x00\x00"


def _blocks_end(data: bytes, pos: int) -> int:
    """Index just past the data sub-blocks starting at ``pos`` (their zero terminator included)."""
    while data[pos]:
        pos += data[pos] + 1
    return pos + 1


def _image_block(encoded: bytes) -> tuple[bytes, bytes, bytes]:
    """(descriptor, colour table, LZW data) of the one image in a single-frame GIF from Pillow."""
    packed = encoded[10]
    table = encoded[13:13 + 3 * 2 ** ((packed & 7) + 1)] if packed & 0x80 else b""
    pos = 13 + len(table)
    while encoded[pos] == 0x21:  # extensions before the image: skipped
        pos = _blocks_end(encoded, pos + 2)
    if encoded[pos] != 0x2C:
        raise ValueError("no image in the encoded frame")
    descriptor = encoded[pos:pos + 10]
    pos += 10
    if descriptor[9] & 0x80:  # the frame's own local table wins
        table = encoded[pos:pos + 3 * 2 ** ((descriptor[9] & 7) + 1)]
        pos += len(table)
    start = pos
    pos = _blocks_end(encoded, pos + 1)  # the LZW minimum code size byte, then its sub-blocks
    return descriptor, table, encoded[start:pos]


def _frame_bytes(image, box: tuple[int, int, int, int], delay_cs: int) -> bytes:
    """Graphic control extension, image descriptor at ``box``, local colour table and data."""
    buffer = io.BytesIO()
    image.crop(box).save(buffer, format="GIF")
    descriptor, table, data = _image_block(buffer.getvalue())
    size_bits = max(len(table) // 3, 2).bit_length() - 2
    control = b"!\xf9\x04" + bytes([1 << 2]) + struct.pack("<H", max(0, min(delay_cs, 0xFFFF))) + b"\x00\x00"
    left, top, right, bottom = box
    packed = ((0x80 | size_bits) if table else 0) | (descriptor[9] & 0x40)  # Pillow interlaces: keep its bit
    header = b"," + struct.pack("<HHHH", left, top, right - left, bottom - top) + bytes([packed])
    return control + header + table + data


def write_gif(out: BinaryIO, frames: Iterable, duration_ms: float) -> int:
    """Stream ``frames`` (Pillow images of one size, any mode) to ``out`` as a looping GIF, each shown
    ``duration_ms``; returns the number of frames taken from ``frames``.

    A delay is whole centiseconds: each frame's is where the clock should be after it, rounded, less
    where it was (24 fps: 4, 4, 4, 5, ...), so the whole plays in its own time (rounding every frame's
    4.17 to 4 played it 4% fast, and 60 fps's 1.67 to 2, 20% slow)."""
    from PIL import ImageChops

    count, previous, pending = 0, None, None
    for image in frames:
        count += 1
        delay = int(round(count * duration_ms / 10.0)) - int(round((count - 1) * duration_ms / 10.0))
        rgb = image.convert("RGB")
        if previous is None:
            width, height = image.size
            out.write(b"GIF89a" + struct.pack("<HH", width, height) + b"\x70\x00\x00" + _LOOP_FOREVER)
            box = (0, 0, width, height)
        else:
            box = ImageChops.difference(previous, rgb).getbbox()
            if box is None:  # the same picture: the one before stays up longer
                pending = (pending[0], pending[1], pending[2] + delay)
                continue
        if pending is not None:
            out.write(_frame_bytes(*pending))
        pending, previous = (image, box, delay), rgb
    if pending is not None:
        out.write(_frame_bytes(*pending))
    out.write(b";")
    return count
