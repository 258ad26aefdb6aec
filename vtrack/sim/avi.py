"""Motion-JPEG in an AVI file, written directly: each frame is compressed by cv2.imencode
(libjpeg-turbo, about 5x faster than the MJPEG encoder inside cv2.VideoWriter) and stored
as one '00dc' chunk of a RIFF AVI 1.0 file with an idx1 index.

Layout: RIFF 'AVI ' { LIST 'hdrl' { avih, LIST 'strl' { strh, strf } }, LIST 'movi'
{ 00dc ... }, idx1 }. Counts and sizes that are known only at the end are patched in then.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterable

import cv2
import numpy as np

from vtrack.errors import InputError
from vtrack.fileio import atomic_open

KEYFRAME = 0x10            # AVIIF_KEYFRAME: every MJPEG frame is one
HAS_INDEX = 0x10           # AVIF_HASINDEX


def _chunk(fourcc: bytes, payload: bytes) -> bytes:
    """A RIFF chunk: id, little-endian size, payload padded to an even length."""
    return fourcc + struct.pack("<I", len(payload)) + payload + b"\0" * (len(payload) % 2)


def _headers(width: int, height: int, fps: float, frames: int, biggest: int) -> bytes:
    """LIST 'hdrl' for one MJPEG video stream."""
    scale = 1000
    rate = round(fps * scale)
    avih = struct.pack("<10I16x", round(1e6 / fps), biggest * round(fps + 1), 0, HAS_INDEX,
                       frames, 0, 1, biggest, width, height)
    strh = struct.pack("<4s4sIHHIIIIIIIi4h", b"vids", b"MJPG", 0, 0, 0, 0, scale, rate, 0,
                       frames, biggest, -1 & 0xFFFFFFFF, 0, 0, 0, width, height)
    strf = struct.pack("<IiiHH4sIiiII", 40, width, height, 1, 24, b"MJPG", width * height * 3,
                       0, 0, 0, 0)
    strl = b"LIST" + struct.pack("<I", 4 + 8 + len(strh) + 8 + len(strf)) + b"strl"
    strl += _chunk(b"strh", strh) + _chunk(b"strf", strf)
    hdrl = b"hdrl" + _chunk(b"avih", avih) + strl
    return b"LIST" + struct.pack("<I", len(hdrl)) + hdrl


def write_mjpeg_avi(path: str | os.PathLike, frames: Iterable[np.ndarray], width: int,
                    height: int, fps: float, quality: int) -> int:
    """Write BGR frames (height, width, 3) as MJPEG AVI at JPEG `quality`, atomically;
    returns the number of frames."""
    header_size = len(_headers(width, height, fps, 0, 0))
    index, sizes = [], []
    with atomic_open(path, "wb") as fh:
        fh.write(b"\0" * (12 + header_size) + b"LIST\0\0\0\0movi")
        offset = 4                                # chunk offsets count from 'movi'
        for frame in frames:
            if frame.shape != (height, width, 3):
                raise InputError(f"{path}: frame of shape {frame.shape}, expected "
                                 f"{(height, width, 3)}")
            ok, jpeg = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, quality])
            if not ok:
                raise InputError(f"{path}: JPEG encoding failed")
            data = jpeg.tobytes()
            fh.write(_chunk(b"00dc", data))
            index.append(struct.pack("<4sIII", b"00dc", KEYFRAME, offset, len(data)))
            sizes.append(len(data))
            offset += 8 + len(data) + len(data) % 2
        movi_size = offset
        fh.write(_chunk(b"idx1", b"".join(index)))
        total = fh.tell()
        fh.seek(0)
        fh.write(b"RIFF" + struct.pack("<I", total - 8) + b"AVI ")
        fh.write(_headers(width, height, fps, len(sizes), max(sizes, default=0)))
        fh.write(b"LIST" + struct.pack("<I", movi_size))
    return len(sizes)
