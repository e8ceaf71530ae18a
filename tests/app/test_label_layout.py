"""Labels of mapped objects never print over each other on the operator's page: objects far apart in the room that
line up along the view (and labels wider on the page than their boxes) are moved up the page until clear."""

import numpy as np

from app.ui.label_layout import FixedLabel, View, any_overprint, screen_stacked, stacked


def view_along_x() -> View:
    """The studio's default kind of view: from behind and above the robot, looking down the room along +x."""
    return View(np.array([-3.0, 0.0, 1.6]), np.array([3.0, 0.0, 0.6]), np.array([0.0, 0.0, 1.0]), np.radians(50.0),
                1000.0, 800.0)


def test_labels_lined_up_along_the_view_are_moved_apart_on_the_page():
    # two boxes side by side 1.5 m apart across the view (apart in the room, but each label is wider on the page
    # than the gap between them: '#1 … seen now #2 …' printed over each other), a nearer and a farther one
    anchors = [np.array(a) for a in ((4.0, 1.0, 0.75), (4.0, -0.5, 0.75), (2.5, 0.3, 0.75), (6.0, 0.0, 0.75))]
    texts = ["#1 box_a E[v]=1.00 · seen now", "#2 E[v]=0.96 · seen 15 s ago", "#3 removed · seen 2 min ago",
             "#4 E[v]=0.50 · seen 4 s ago"]
    world = stacked(anchors)
    np.testing.assert_allclose(world, anchors)  # nothing within 0.8 m of another: the room-space rule moves none
    view = view_along_x()
    assert any_overprint(world, texts, view)
    placed = screen_stacked(world, texts, view)
    assert not any_overprint(placed, texts, view)
    np.testing.assert_allclose(placed[0], anchors[0])  # the first stays where it was
    assert all(p[2] >= a[2] for p, a in zip(placed, anchors, strict=True))  # moved up, never down


def test_without_a_browser_the_room_space_stacking_stands():
    anchors = [np.array([2.0, 1.0, 1.2]), np.array([2.35, 1.1, 1.2])]
    world = stacked(anchors)
    assert abs(world[1][2] - world[0][2]) >= 0.22 - 1e-9
    np.testing.assert_allclose(screen_stacked(world, ["#1", "#2"], None), world)


def test_a_label_behind_the_camera_is_left_alone():
    view = view_along_x()
    behind = [np.array([-6.0, 0.0, 0.5]), np.array([-6.0, 0.0, 0.5])]
    np.testing.assert_allclose(screen_stacked(behind, ["#1", "#2"], view), behind)


def test_an_object_label_keeps_clear_of_a_subtask_label_that_does_not_move():
    # an EE goal 0.4 m above a box: its label '2. ee: pick' and the box's '#2 …' at one spot on the page
    view = view_along_x()
    goal = (np.array([4.0, 0.0, 1.35]), "2. ee: pick")
    box = [np.array([4.0, 0.05, 1.35])]
    text = ["#2 box_a E[v]=1.00 · seen now"]
    assert any_overprint([goal[0], box[0]], [goal[1], text[0]], view)
    placed = screen_stacked(box, text, view, fixed=[goal])
    assert not any_overprint([goal[0], placed[0]], [goal[1], text[0]], view)
    assert placed[0][2] > box[0][2]


def test_a_label_on_the_base_follows_the_base():
    T = np.eye(4)
    T[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]  # yaw 90°
    T[:3, 3] = [2.0, 1.0, 0.0]
    at = np.array([0.5, 0.0, 1.0])
    np.testing.assert_allclose(FixedLabel(at, "1. ee: x", on_base=True).world(T), [2.0, 1.5, 1.0])
    np.testing.assert_allclose(FixedLabel(at, "1. ee: x").world(T), at)
