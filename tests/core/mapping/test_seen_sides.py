"""Which side faces a mapped box's points show, and a box refitted once a moved box's old place is no longer well
supported (the fit is what anchors are placed on)."""

import numpy as np

from core.mapping.box_fit import BoxFit, fit_upright_box, seen_sides
from core.mapping.tracked_object import TrackedObject
from core.params import MappingParams


def face_points(x0: float, x1: float, y0: float, y1: float, step: float = 0.02, front: bool = True,
                right: bool = False) -> np.ndarray:
    """The top of a 0.6 m tall box over [x0, x1] × [y0, y1], its front (−x) face, and its right (−y) face."""
    xs, ys, zs = np.arange(x0, x1, step), np.arange(y0, y1, step), np.arange(0.02, 0.6, step)
    top = np.array([(x, y, 0.6) for x in xs for y in ys])
    parts = [top]
    if front:
        parts.append(np.array([(x0, y, z) for y in ys for z in zs]))
    if right:
        parts.append(np.array([(x, y0, z) for x in xs for z in zs]))
    return np.vstack(parts)


def test_a_box_seen_from_its_front_shows_its_front_face_only():
    pts = face_points(2.2, 2.7, -0.3, 0.3)  # the top seen to 2.7 only: the fit is 0.5 deep
    fit = fit_upright_box(pts, floor_z=0.0, floor_snap_m=0.1, yaw=0.0)
    assert abs(fit.extent[0] - 0.5) < 0.03
    np.testing.assert_array_equal(seen_sides(pts, fit), [[True, False], [False, False]])
    corner = face_points(2.2, 2.7, -0.3, 0.3, right=True)
    np.testing.assert_array_equal(seen_sides(corner, fit_upright_box(corner, 0.0, 0.1, yaw=0.0)),
                                  [[True, False], [True, False]])
    turned = BoxFit(fit.centre, np.pi / 2, fit.extent[[1, 0, 2]])  # the same box in axes turned a quarter
    np.testing.assert_array_equal(seen_sides(pts, turned), [[False, False], [False, True]])


def test_the_fit_follows_when_a_moved_boxs_old_place_is_no_longer_well_supported():
    """A box pushed 0.5 m along y whose new place was fused into the same object: the old place, seen once, falls
    under a quarter of the median count as the new place is seen again and again; the voxel count does not
    change, and the box is refitted to the new place all the same (it kept both places, 1.1 m, before)."""
    p = MappingParams()
    old, new = face_points(2.2, 2.8, -0.3, 0.3), face_points(2.2, 2.8, 0.2, 0.8)
    obj = TrackedObject(1, old, p.voxel_m, p.prior(), floor_snap_m=0.1)
    obj.integrate(new)
    assert obj.fit.extent[1] > 1.0 or obj.fit.extent[0] > 1.0  # both places, one box
    for _ in range(20):
        obj.integrate(new)
    centre = obj.pose[:3, 3]
    assert abs(centre[1] - 0.5) < 0.03 and max(obj.fit.extent[:2]) < 0.65, (centre, obj.fit.extent)
