"""A byte-level C3D writer for tests: integer or float points, Intel, DEC or MIPS byte order, analogs.

Written from the C3D format's description (c3d.org, "The C3D File Format User Guide"), not from
ezc3d or usdgaze, so files it writes check the reader against the format itself:

* a 512-byte header block; the parameter section from block 2; the data after it;
* ``POINT:SCALE`` negative: points stored as 32-bit floats; positive: as 16-bit integers, and a
  coordinate is the integer times the scale;
* each point's fourth word: the residual (times ``|scale|`` in integer files; its low byte, with the
  camera mask in the high byte) or -1 where the marker was not seen;
* processor type 84 (Intel: little-endian IEEE), 85 (DEC: little-endian integers, VAX F floats:
  16-bit words swapped and the value 4 times the IEEE bits' value), 86 (MIPS: big-endian IEEE).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

INTEL, DEC, MIPS = 84, 85, 86


class _Enc:
    """Numbers as bytes in one processor's format."""

    def __init__(self, processor: int) -> None:
        self.processor = processor
        self.order = ">" if processor == MIPS else "<"

    def i16(self, values) -> bytes:
        values = np.atleast_1d(np.asarray(values, dtype=np.int64))
        return struct.pack(f"{self.order}{values.size}h", *values.ravel().tolist())

    def f32(self, values) -> bytes:
        values = np.atleast_1d(np.asarray(values, dtype=np.float64)).ravel()
        if self.processor != DEC:
            return struct.pack(f"{self.order}{values.size}f", *values.tolist())
        # VAX F: the IEEE bits of 4x the value (exponent bias 128, hidden bit at 0.1), words swapped.
        raw = struct.pack(f"<{values.size}f", *(4.0 * values).tolist())
        return b"".join(raw[k + 2 : k + 4] + raw[k : k + 2] for k in range(0, len(raw), 4))


def _param(enc: _Enc, group_id: int, name: str, value, kind: str) -> bytes:
    """One parameter record (without its next-offset fix-up, done by the caller)."""
    if kind == "char":
        texts = [value] if isinstance(value, str) else list(value)
        width = max(1, max(len(t) for t in texts))
        data = b"".join(t.ljust(width).encode("ascii") for t in texts)
        dims = [width] if isinstance(value, str) else [width, len(texts)]
        code = -1
    elif kind == "int":
        values = np.atleast_1d(value)
        data, code = enc.i16(values), 2
        dims = [] if np.ndim(value) == 0 else [len(values)]
    else:
        values = np.atleast_1d(value)
        data, code = enc.f32(values), 4
        dims = [] if np.ndim(value) == 0 else [len(values)]
    body = struct.pack("bB", code, len(dims)) + bytes(dims) + data + b"\x00"  # no description
    head = struct.pack("bb", len(name), group_id) + name.encode("ascii")
    return head + enc.i16(2 + len(body)) + body


def _group(enc: _Enc, group_id: int, name: str) -> bytes:
    head = struct.pack("bb", len(name), -group_id) + name.encode("ascii")
    return head + enc.i16(3) + b"\x00"


def write_c3d_bytes(path: Path, labels: list[str], points: np.ndarray, rate: float, *, integer: bool = False,
                    scale: float = 0.1, processor: int = INTEL, first_frame: int = 1, units: str = "mm",
                    analog_channels: int = 0, analog_per_frame: int = 0, residual: float = 1.0) -> None:
    """Write ``points (F, M, 3)`` (NaN = not seen) as a C3D file.

    ``integer``: 16-bit storage with ``POINT:SCALE = scale`` (> 0), else float (``-scale``).
    ``analog_channels`` x ``analog_per_frame`` analog samples follow each frame's points (a ramp).
    """
    enc = _Enc(processor)
    frames, markers, _ = points.shape
    used_scale = abs(scale) if integer else -abs(scale)
    n_analog = analog_channels * analog_per_frame
    analog_rate = rate * analog_per_frame
    params = [_group(enc, 1, "POINT"),
              _param(enc, 1, "USED", markers, "int"),
              _param(enc, 1, "FRAMES", frames, "int"),
              _param(enc, 1, "SCALE", used_scale, "float"),
              _param(enc, 1, "RATE", rate, "float"),
              _param(enc, 1, "DATA_START", 0, "int"),  # patched below
              _param(enc, 1, "LABELS", [str(s) for s in labels], "char"),
              _param(enc, 1, "DESCRIPTIONS", [" "] * markers, "char"),
              _param(enc, 1, "UNITS", units, "char"),
              _group(enc, 2, "ANALOG"),
              _param(enc, 2, "USED", analog_channels, "int"),
              _param(enc, 2, "RATE", analog_rate, "float"),
              _param(enc, 2, "GEN_SCALE", 1.0, "float")]
    if analog_channels:
        params += [_param(enc, 2, "LABELS", [f"A{i}" for i in range(analog_channels)], "char"),
                   _param(enc, 2, "SCALE", [1.0] * analog_channels, "float"),
                   _param(enc, 2, "OFFSET", [0] * analog_channels, "int"),
                   _param(enc, 2, "UNITS", ["V"] * analog_channels, "char"),
                   _param(enc, 2, "DESCRIPTIONS", [" "] * analog_channels, "char")]
    size = 4 + sum(len(p) for p in params) + 4  # + the terminating record
    n_param_blocks = (size + 511) // 512
    data_start = 2 + n_param_blocks
    for k, p in enumerate(params):  # DATA_START's value is the record's last 2 bytes before its description
        if p[2:12] == b"DATA_START":
            params[k] = p[:-3] + enc.i16(data_start) + b"\x00"
    section = bytes([1, 0x50, n_param_blocks, processor]) + b"".join(params) + b"\x00\x00" + enc.i16(0)
    section = section.ljust(n_param_blocks * 512, b"\x00")

    header = bytearray(512)
    header[0:2] = bytes([2, 0x50])
    header[2:12] = enc.i16([markers, n_analog, first_frame, first_frame + frames - 1, 10])
    header[12:16] = enc.f32(used_scale)
    header[16:20] = enc.i16([data_start, analog_per_frame])
    header[20:24] = enc.f32(rate)

    body = bytearray()
    for f in range(frames):
        words = np.zeros((markers, 4))
        for m in range(markers):
            p = points[f, m]
            if np.isnan(p).any():
                words[m] = (0.0, 0.0, 0.0, -1.0)
            elif integer:
                words[m, :3] = np.round(p / scale)
                words[m, 3] = min(255, int(round(residual / scale)))  # low byte: residual; camera mask 0
            else:
                words[m] = (*p, residual)
        body += enc.i16(words) if integer else enc.f32(words)
        ramp = np.arange(n_analog) + f
        body += enc.i16(ramp) if integer else enc.f32(ramp)
    body = bytes(body).ljust(((len(body) + 511) // 512) * 512, b"\x00")
    Path(path).write_bytes(bytes(header) + section + body)
