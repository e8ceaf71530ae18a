import numpy as np
import pytest

from core.scene import Box, random_scene
from core.sim.ground_truth import box_signed_distance
from tasks.occupancy import OccupancyGrid
from tasks.path_planner import NoPathError, plan_path


def surface_points(boxes, n=600, seed=0):
    rng = np.random.default_rng(seed)
    return np.concatenate([rng.uniform(-0.5, 0.5, (n, 3)) * b.size + b.position for b in boxes])


def test_path_avoids_inflated_boxes_in_random_scenes():
    for seed in range(5):
        scene = random_scene(seed)
        grid = OccupancyGrid.from_points(surface_points(scene.boxes), (-6, 6, -5, 5), 0.1, 0.6)
        path = plan_path(grid, np.array(scene.robot_start[:2]), [np.array(scene.goal)])
        np.testing.assert_allclose(path[0], scene.robot_start[:2])
        np.testing.assert_allclose(path[-1], scene.goal)
        pts = np.column_stack([path, np.full(len(path), 0.3)])
        clearance = np.min([box_signed_distance(pts, b) for b in scene.boxes], axis=0)
        assert clearance.min() > 0.4, seed  # inflation 0.6 minus grid discretisation (cell diagonal 0.14)
        assert np.all(np.linalg.norm(np.diff(path, axis=0), axis=1) <= 0.1 + 1e-9)


def test_waypoints_are_visited_in_order():
    grid = OccupancyGrid.from_points(np.zeros((0, 3)), (-5, 5, -5, 5), 0.1, 0.6)
    path = plan_path(grid, np.zeros(2), [np.array([2.0, 0.0]), np.array([2.0, 2.0])])
    d_first = np.linalg.norm(path - [2.0, 0.0], axis=1)
    k = int(np.argmin(d_first))
    assert d_first[k] < 0.06 and np.all(path[k:, 1] >= -1e-9)
    assert len(path) * 0.1 == pytest.approx(4.0, abs=0.25)  # straight legs after shortcutting


def test_start_inside_inflation_can_leave_and_blocked_goal_raises():
    box = Box("b", (1.0, 0.0, 0.3))
    grid = OccupancyGrid.from_points(surface_points([box]), (-5, 5, -5, 5), 0.1, 0.6)
    path = plan_path(grid, np.array([0.3, 0.0]), [np.array([-2.0, 0.0])])
    assert np.linalg.norm(path[-1] - [-2.0, 0.0]) < 1e-9
    with pytest.raises(NoPathError, match="too close"):
        plan_path(grid, np.array([-2.0, 0.0]), [np.array([1.0, 0.0])])


def test_enclosed_goal_has_no_path():
    ring = [Box(f"r{i}", (2.0 * np.cos(a), 2.0 * np.sin(a), 0.3)) for i, a in enumerate(np.linspace(0, 2 * np.pi, 24))]
    grid = OccupancyGrid.from_points(surface_points(ring), (-5, 5, -5, 5), 0.1, 0.3)
    with pytest.raises(NoPathError, match=r"no path to the goal \(0.00, 0.00\)"):
        plan_path(grid, np.array([4.0, 0.0]), [np.array([0.0, 0.0])])


def test_blocked_waypoint_skipped_and_goal_snapped():
    box = Box("b", (2.0, 0.0, 0.3))
    grid = OccupancyGrid.from_points(surface_points([box]), (-5, 5, -5, 5), 0.1, 0.8)
    notes = []
    near_face = np.array([2.0 - 0.3 - 0.75, 0.0])  # 5 cm inside the inflated region in front of the box
    path = plan_path(grid, np.array([-2.0, 0.0]), [np.array([2.0, 0.0]), near_face], notes=notes)
    assert "skipped" in notes[0] and "going to" in notes[1]
    assert np.linalg.norm(path[-1] - near_face) < 0.3
    assert grid.is_free(path[-1])


def test_a_goal_in_the_start_cell_is_still_the_path_end():
    """A robot already inside its goal's grid cell gets a path to the goal itself, not one that stops where it
    stands (that once held the base up to a cell's diagonal off its goal and logged a 0 m "goal moved")."""
    grid = OccupancyGrid.from_points(np.zeros((0, 3)), (-5, 5, -5, 5), 0.1, 0.6)
    for start, goal in (([0.03, 0.02], [0.0, 0.0]), ([0.03, 0.02], [0.08, 0.09]), ([0.05, 0.05], [0.05, 0.05])):
        assert grid.cell(np.array(start)) == grid.cell(np.array(goal))
        path = plan_path(grid, np.array(start), [np.array(goal)])
        np.testing.assert_allclose(path[0], start)
        np.testing.assert_allclose(path[-1], goal)


@pytest.mark.parametrize("where", ["spread", "corner", "one point", "beyond the bounds"])
def test_inflation_is_measured_from_the_points_to_within_a_sub_cell(where):
    """A cell is blocked exactly when its centre lies within `inflation_m` of a point (to half a sub-cell's
    diagonal, 2.4 cm at 0.1 m cells), wherever in its cell the point sits, and wherever the points lie on the grid
    (the transform runs on the block within reach of them)."""
    rng = np.random.default_rng(5)
    xy = {"spread": rng.uniform(-3.0, 3.0, (40, 2)), "corner": rng.uniform([4.6, -5.0], [5.0, -4.7], (10, 2)),
          "one point": np.array([[0.37, -1.21]]), "beyond the bounds": np.array([[5.3, 0.2], [-1.0, -5.4]])}[where]
    points = np.c_[xy, np.full(len(xy), 0.3)]
    grid = OccupancyGrid.from_points(points, (-5, 5, -5, 5), 0.1, 0.8)
    i, j = np.meshgrid(np.arange(100), np.arange(100), indexing="ij")
    centres = grid.origin + (np.c_[i.ravel(), j.ravel()] + 0.5) * 0.1
    exact = np.min(np.linalg.norm(centres[:, None] - points[None, :, :2], axis=2), axis=1).reshape(100, 100)
    inside = np.all((xy >= -5) & (xy < 5), axis=1).any()  # points outside the grid mark nothing
    tolerance = 0.1 / 3 * np.sqrt(2) / 2
    assert np.all(grid.blocked[exact <= 0.8 - tolerance]) or not inside
    assert not np.any(grid.blocked[exact > 0.8 + tolerance])
    assert grid.blocked.any() == inside


def test_the_shipped_aisle_leaves_a_path_round_all_four_sides():
    """The aisle example's 1.9 m aisles, planned with the controller's clearance (0.8 m) on faces mapped 2 cm
    off the truth: the corridor (0.3 m wide) stays open, as the object map's faces need."""
    from core.scene import load_scene
    from tasks.sequence_file import EXAMPLES_DIR, load_sequence

    sequence = load_sequence(EXAMPLES_DIR / "aisle_laps.yaml")
    scene = load_scene(EXAMPLES_DIR / "../../core/scenes/aisle.yaml")
    rng = np.random.default_rng(0)
    for offset in (0.02, 0.0, -0.02):  # faces mapped 2 cm out, in place and 2 cm in
        faces = _box_faces(scene.boxes, offset)
        grid = OccupancyGrid.from_points(faces + rng.normal(0.0, 0.005, faces.shape), (-8, 8, -8, 8), 0.1, 0.8)
        here = np.array(scene.robot_start[:2])
        for sub in sequence.subtasks[:5]:
            if sub.kind == "base":
                here = plan_path(grid, here, [w.xy() for w in sub.path()])[-1]
        assert np.linalg.norm(here - np.array(sequence.subtasks[4].target.xy())) < 0.15, offset


def _box_faces(boxes, offset_m: float, spacing_m: float = 0.02) -> np.ndarray:
    """Points on the four vertical faces of each box at half its height, each face moved `offset_m` out."""
    out = []
    for b in boxes:
        hx, hy = b.size[0] / 2 + offset_m, b.size[1] / 2 + offset_m
        u = np.arange(-hx, hx + 1e-9, spacing_m)
        v = np.arange(-hy, hy + 1e-9, spacing_m)
        local = np.concatenate([np.c_[u, np.full_like(u, hy)], np.c_[u, np.full_like(u, -hy)],
                                np.c_[np.full_like(v, hx), v], np.c_[np.full_like(v, -hx), v]])
        c, s = np.cos(b.yaw), np.sin(b.yaw)
        xy = local @ np.array([[c, s], [-s, c]]) + b.position[:2]
        out.append(np.c_[xy, np.full(len(xy), b.position[2])])
    return np.concatenate(out)


def test_a_waypoint_without_a_path_is_named_by_its_own_number():
    """After the first waypoint was passed, the planner's goals start at the second: the message says 2."""
    ring = [Box(f"r{i}", (3.0 + 2.0 * np.cos(a), 2.0 * np.sin(a), 0.3))
            for i, a in enumerate(np.linspace(0, 2 * np.pi, 24))]
    grid = OccupancyGrid.from_points(surface_points(ring), (-6, 6, -6, 6), 0.1, 0.3)
    with pytest.raises(NoPathError, match=r"no path to waypoint 2 \(3.00, 0.00\)"):
        plan_path(grid, np.array([-2.0, 0.0]), [np.array([3.0, 0.0]), np.array([-3.0, 0.0])], first_waypoint=2)


def _grid_graph_costs(blocked: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """Shortest 8-connected path cost (no corner cutting) from `start` to every cell, by Dijkstra (scipy)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    nx, ny = blocked.shape
    rows, cols, costs = [], [], []
    for i in range(nx):
        for j in range(ny):
            if blocked[i, j]:
                continue
            for dx, dy in ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)):
                a, b = i + dx, j + dy
                if not (0 <= a < nx and 0 <= b < ny) or blocked[a, b]:
                    continue
                if dx and dy and (blocked[i + dx, j] or blocked[i, j + dy]):
                    continue
                rows.append(i * ny + j)
                cols.append(a * ny + b)
                costs.append(np.hypot(dx, dy))
    graph = coo_matrix((costs, (rows, cols)), shape=(nx * ny, nx * ny)).tocsr()
    return dijkstra(graph, indices=start[0] * ny + start[1]).reshape(nx, ny)


def test_astar_finds_a_shortest_path_on_the_grid():
    """A* (with its flat-index search) returns a connected path of free cells whose length is the grid graph's
    shortest, or refuses exactly when the goal is unreachable."""
    from tasks.path_planner import astar

    rng = np.random.default_rng(3)
    for _ in range(30):
        blocked = rng.random((rng.integers(5, 30), rng.integers(5, 30))) < rng.uniform(0.1, 0.4)
        grid = OccupancyGrid(np.zeros(2), 0.1, blocked)
        free = np.argwhere(~blocked)
        start, goal = (tuple(int(v) for v in free[k]) for k in rng.choice(len(free), 2))
        best = _grid_graph_costs(blocked, start)[goal]
        if not np.isfinite(best):
            with pytest.raises(NoPathError):
                astar(grid, start, goal)
            continue
        path = np.array(astar(grid, start, goal))
        steps = np.diff(path, axis=0)
        assert tuple(path[0]) == start and tuple(path[-1]) == goal
        assert not blocked[path[:, 0], path[:, 1]].any() and np.abs(steps).max(initial=0) <= 1
        assert np.hypot(steps[:, 0], steps[:, 1]).sum() == pytest.approx(best)


def test_segments_free_answers_as_each_segment_alone():
    """The batched line-of-sight check gives, per end, the answer of sampling that one segment every half cell
    (`np.linspace`): horizontal, vertical, zero-length and diagonal segments alike."""
    rng = np.random.default_rng(4)
    blocked = rng.random((60, 50)) < 0.03
    grid = OccupancyGrid(np.array([-3.0, -2.5]), 0.1, blocked)
    a = np.array([0.13, -0.41])
    ends = np.vstack([rng.uniform([-3, -2.5], [3, 2.5], (200, 2)), [a[0], 2.0], [-2.0, a[1]], a])

    def alone(b: np.ndarray) -> bool:
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / 0.05)) + 1)
        idx = np.clip(np.floor((np.linspace(a, b, n) - grid.origin) / 0.1).astype(int), 0, np.array(blocked.shape) - 1)
        return not blocked[idx[:, 0], idx[:, 1]].any()

    expected = [alone(b) for b in ends]
    assert grid.segments_free(a, ends).tolist() == expected
    assert 0 < sum(expected) < len(expected)
