"""The binary layout of a depth frame on the robot link (one WebSocket binary message per frame).

    offset  size  content
    0       4     magic b"HDF1"
    4       4     header length N, uint32 little-endian (1 ≤ N ≤ 65536)
    8       N     header: UTF-8 JSON of a `DepthFrameHeader` (t, camera, width, height, encoding,
                  K 3×3, T_world_camera 4×4, range_m)
    8 + N   P     pixels, row-major, little-endian: float32 metres ('float32_m', P = 4·W·H) or
                  uint16 millimetres ('uint16_mm', P = 2·W·H); 0 means no return

A message whose length is not exactly 8 + N + P, whose header does not validate, whose K is not a
pinhole matrix for this image, whose pose is not rigid, or whose pixels are NaN, infinite or negative is
refused with `FrameFormatError` (its text is sent back to the driver).
"""

from __future__ import annotations

import struct

import numpy as np
from pydantic import ValidationError

from app.bridge.protocol import DepthEncoding, DepthFrameHeader, validation_text
from core.errors import StudioError
from core.types import DepthFrame

MAGIC = b"HDF1"
PREFIX = struct.Struct("<4sI")
MAX_HEADER_BYTES = 65536
PIXEL_DTYPES = {"float32_m": np.dtype("<f4"), "uint16_mm": np.dtype("<u2")}
RIGID_TOLERANCE = 1e-3
"""How far T_world_camera's rotation may be from orthonormal, and its last row from [0, 0, 0, 1]."""


class FrameFormatError(StudioError, ValueError):
    """A binary message that is not a valid depth frame; the message says what is wrong."""


def encode_depth_frame(frame: DepthFrame, encoding: DepthEncoding = "float32_m") -> bytes:
    """The binary message for `frame` (depth in metres, 0 = no return)."""
    depth = np.asarray(frame.depth)
    header = DepthFrameHeader(t=frame.t, camera=frame.camera, width=depth.shape[1], height=depth.shape[0],
                              encoding=encoding, K=np.asarray(frame.K).tolist(),
                              T_world_camera=np.asarray(frame.T_world_camera).tolist(), range_m=frame.range_m)
    if encoding == "uint16_mm":
        pixels = np.clip(np.rint(depth * 1000.0), 0, 65535).astype(PIXEL_DTYPES[encoding])
    else:
        pixels = depth.astype(PIXEL_DTYPES[encoding])
    text = header.model_dump_json().encode()
    return PREFIX.pack(MAGIC, len(text)) + text + pixels.tobytes()


def _split(data: bytes) -> tuple[bytes, memoryview]:
    if len(data) < PREFIX.size:
        raise FrameFormatError(f"truncated frame: {len(data)} bytes, the prefix alone is {PREFIX.size}")
    magic, n = PREFIX.unpack_from(data)
    if magic != MAGIC:
        raise FrameFormatError(f"bad magic {magic!r}: a depth frame starts with {MAGIC!r}")
    if not 1 <= n <= MAX_HEADER_BYTES:
        raise FrameFormatError(f"header length {n} outside 1..{MAX_HEADER_BYTES}")
    if len(data) < PREFIX.size + n:
        raise FrameFormatError(f"truncated frame: header of {n} bytes announced, {len(data) - PREFIX.size} present")
    view = memoryview(data)
    return bytes(view[PREFIX.size:PREFIX.size + n]), view[PREFIX.size + n:]


def _header(text: bytes) -> DepthFrameHeader:
    try:
        return DepthFrameHeader.model_validate_json(text)
    except ValidationError as err:
        raise FrameFormatError(f"bad header: {validation_text(err)}") from err


def _check_rigid(T: np.ndarray) -> None:
    R = T[:3, :3]
    if not (np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=RIGID_TOLERANCE)
            and np.allclose(R.T @ R, np.eye(3), atol=RIGID_TOLERANCE) and np.linalg.det(R) > 0.0):
        raise FrameFormatError("T_world_camera is not a rigid transform (rotation orthonormal, last row 0 0 0 1)")


def _check_pinhole(K: np.ndarray, width: int, height: int) -> None:
    """K = [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0 and the principal point on the image
    (an all-zero or singular K would divide by zero when the map back-projects pixels)."""
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if not (np.allclose(K[2], [0.0, 0.0, 1.0], atol=1e-6) and abs(K[1, 0]) <= 1e-6):
        raise FrameFormatError("K is not a pinhole matrix: its rows must be [fx, s, cx], [0, fy, cy], [0, 0, 1]")
    if not (fx > 0.0 and fy > 0.0):
        raise FrameFormatError(f"K has focal lengths fx = {fx:g}, fy = {fy:g} px; both must be positive")
    if not (0.0 <= cx <= width and 0.0 <= cy <= height):
        raise FrameFormatError(f"K's principal point ({cx:g}, {cy:g}) px lies outside the {width}×{height} image "
                               "(intrinsics of another resolution?)")


def _pixels(header: DepthFrameHeader, payload: memoryview) -> np.ndarray:
    dtype = PIXEL_DTYPES[header.encoding]
    expected = header.width * header.height * dtype.itemsize
    if len(payload) != expected:
        raise FrameFormatError(f"payload of {len(payload)} bytes; {header.width}×{header.height} {header.encoding} "
                               f"needs exactly {expected}")
    raw = np.frombuffer(payload, dtype=dtype).reshape(header.height, header.width)
    if header.encoding == "uint16_mm":
        return raw.astype(np.float32) / np.float32(1000.0)
    depth = raw.astype(np.float32)
    bad = int(np.count_nonzero(~np.isfinite(depth)))
    if bad:
        raise FrameFormatError(f"{bad} depth pixels are NaN or infinite; send 0 for 'no return'")
    negative = int(np.count_nonzero(depth < 0.0))
    if negative:
        raise FrameFormatError(f"{negative} depth pixels are negative; depth is in metres, 0 for 'no return'")
    return depth


def decode_depth_frame(data: bytes) -> DepthFrame:
    """Parse and check one binary message; raises `FrameFormatError` saying what is wrong."""
    text, payload = _split(data)
    header = _header(text)
    T = np.array(header.T_world_camera, dtype=float)
    _check_rigid(T)
    K = np.array(header.K, dtype=float)
    _check_pinhole(K, header.width, header.height)
    depth = _pixels(header, payload)
    return DepthFrame(t=header.t, camera=header.camera, depth=depth, K=K, T_world_camera=T, range_m=header.range_m)
