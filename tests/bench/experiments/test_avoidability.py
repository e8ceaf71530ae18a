"""The physical bound of E3: which extreme manoeuvres clear a box pushed in front of the base."""

from bench.experiments.avoidability import Push, avoidable_by

BASE = (0.48, 0.395)


def ahead(gap_m: float, lateral_m: float = 0.0, yaw: float = 0.0) -> Push:
    """A 0.6 m box whose near face is `gap_m` in front of the base's front face."""
    return Push(0.48 + gap_m + 0.3, lateral_m, yaw, (0.6, 0.6))


def test_braking_needs_the_stopping_distance():
    # 1 m/s, 2 m/s²: 0.25 m to stop without delay, 0.75 m with 0.5 s
    assert avoidable_by(ahead(0.2), BASE, 1.0, 0.0, 2.0, 1.0) == []
    assert "brake" in avoidable_by(ahead(0.3), BASE, 1.0, 0.0, 2.0, 1.0)
    assert "brake" not in avoidable_by(ahead(0.7), BASE, 1.0, 0.5, 2.0, 1.0)
    assert "brake" in avoidable_by(ahead(0.8), BASE, 1.0, 0.5, 2.0, 1.0)


def test_a_box_at_the_edge_of_the_path_is_passed_by_a_sidestep():
    edge = ahead(0.2, lateral_m=0.66)  # overlaps the path by 3.5 cm on the left
    ways = avoidable_by(edge, BASE, 1.0, 0.0, 2.0, 1.0)
    assert "brake" not in ways and "right" in ways and "left" not in ways

