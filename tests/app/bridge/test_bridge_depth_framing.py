"""The binary depth-frame layout: round trips, and every malformed message refused with a reason."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from app.bridge.depth_framing import MAGIC, FrameFormatError, decode_depth_frame, encode_depth_frame
from core.types import DepthFrame

pytestmark = pytest.mark.wallclock


def _frame(depth: np.ndarray | None = None) -> DepthFrame:
    rng = np.random.default_rng(1)
    depth = rng.uniform(0.0, 3.0, (24, 32)).astype(np.float32) if depth is None else depth
    T = np.eye(4)
    T[:3, 3] = [1.0, 2.0, 0.5]
    K = np.array([[30.0, 0.0, 15.5], [0.0, 30.0, 11.5], [0.0, 0.0, 1.0]])
    return DepthFrame(t=1.25, camera="hand", depth=depth, K=K, T_world_camera=T, range_m=3.0)


def _with_header(data: bytes, **changes) -> bytes:
    n = struct.unpack_from("<I", data, 4)[0]
    header = json.loads(data[8:8 + n]) | changes
    text = json.dumps(header).encode()
    return MAGIC + struct.pack("<I", len(text)) + text + data[8 + n:]


def test_float32_round_trip_is_exact() -> None:
    frame = _frame()
    back = decode_depth_frame(encode_depth_frame(frame))
    assert back.t == frame.t and back.camera == frame.camera and back.range_m == frame.range_m
    np.testing.assert_array_equal(back.depth, frame.depth)
    np.testing.assert_array_equal(back.K, frame.K)
    np.testing.assert_array_equal(back.T_world_camera, frame.T_world_camera)


def test_uint16_millimetres_round_trip_within_half_a_millimetre() -> None:
    frame = _frame()
    back = decode_depth_frame(encode_depth_frame(frame, "uint16_mm"))
    assert back.depth.dtype == np.float32
    assert np.max(np.abs(back.depth - frame.depth)) <= 0.0005 + 1e-6


@pytest.mark.parametrize(("cut", "reason"), [(5, "truncated"), (20, "truncated"), (-1, "needs exactly"),
                                             (-100, "needs exactly")])
def test_truncated_messages_are_refused(cut: int, reason: str) -> None:
    data = encode_depth_frame(_frame())
    with pytest.raises(FrameFormatError, match=reason):
        decode_depth_frame(data[:cut])


def test_bad_magic_and_header_length_are_refused() -> None:
    data = encode_depth_frame(_frame())
    with pytest.raises(FrameFormatError, match="magic"):
        decode_depth_frame(b"JUNK" + data[4:])
    with pytest.raises(FrameFormatError, match="header length"):
        decode_depth_frame(MAGIC + struct.pack("<I", 10**7) + data[8:])


@pytest.mark.parametrize(("changes", "field"), [({"K": [[1, 0, 0], [0, 1, 0]]}, "K"),
                                                ({"camera": "hand cam"}, "camera"),
                                                ({"t": float("nan")}, "t"),
                                                ({"extra": 1}, "extra"),
                                                ({"width": 0}, "width")])
def test_bad_headers_name_the_field(changes: dict, field: str) -> None:
    data = _with_header(encode_depth_frame(_frame()), **changes)
    with pytest.raises(FrameFormatError, match=f"bad header: {field}"):
        decode_depth_frame(data)


def test_header_that_does_not_match_the_payload_is_refused() -> None:
    data = _with_header(encode_depth_frame(_frame()), width=31)
    with pytest.raises(FrameFormatError, match="needs exactly"):
        decode_depth_frame(data)


def test_nan_and_negative_depth_are_refused() -> None:
    depth = _frame().depth.copy()
    depth[3, 4] = np.nan
    with pytest.raises(FrameFormatError, match="1 depth pixels are NaN"):
        decode_depth_frame(encode_depth_frame(_frame(depth)))
    depth[3, 4] = -1.0
    with pytest.raises(FrameFormatError, match="negative"):
        decode_depth_frame(encode_depth_frame(_frame(depth)))


def test_a_pose_that_is_not_rigid_is_refused() -> None:
    data = _with_header(encode_depth_frame(_frame()), T_world_camera=(2 * np.eye(4)).tolist())
    with pytest.raises(FrameFormatError, match="rigid"):
        decode_depth_frame(data)


@pytest.mark.parametrize(("K", "reason"), [
    (np.zeros((3, 3)), "pinhole"),                                                   # all zero
    ([[30.0, 0.0, 15.5], [0.0, 0.0, 11.5], [0.0, 0.0, 1.0]], "focal lengths"),       # singular: fy = 0
    ([[-30.0, 0.0, 15.5], [0.0, 30.0, 11.5], [0.0, 0.0, 1.0]], "focal lengths"),
    ([[30.0, 0.0, 15.5], [0.0, 30.0, 11.5], [0.0, 0.0, 0.0]], "pinhole"),            # last row not 0 0 1
    ([[30.0, 0.0, 319.5], [0.0, 30.0, 239.5], [0.0, 0.0, 1.0]], "principal point"),  # K of a 640×480 image
    ([[float("nan"), 0.0, 15.5], [0.0, 30.0, 11.5], [0.0, 0.0, 1.0]], "bad header: K"),
    ([[float("inf"), 0.0, 15.5], [0.0, 30.0, 11.5], [0.0, 0.0, 1.0]], "bad header: K"),
])
def test_an_intrinsic_matrix_that_is_not_a_pinhole_of_this_image_is_refused(K, reason: str) -> None:
    """The map back-projects with K⁻¹: a zero, singular, non-finite or foreign K never reaches it."""
    data = _with_header(encode_depth_frame(_frame()), K=np.asarray(K).tolist())
    with pytest.raises(FrameFormatError, match=reason):
        decode_depth_frame(data)


@pytest.mark.parametrize("changes", [{"width": 32.0}, {"width": True}, {"t": True}, {"range_m": "3"}])
def test_numbers_in_the_header_are_typed_strictly(changes: dict) -> None:
    """Integers are integers (32.0 is refused), and no boolean or string passes for a number."""
    data = _with_header(encode_depth_frame(_frame()), **changes)
    with pytest.raises(FrameFormatError, match=f"bad header: {next(iter(changes))}"):
        decode_depth_frame(data)
