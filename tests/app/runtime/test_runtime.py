"""The closed loop in lockstep and live mode, with the real controller, maps and MuJoCo."""

import gzip
import json
import subprocess
import sys

import numpy as np
import pytest

from app.recording import Recorder, read_recording
from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from core.scene import Box, Scene, random_scene
from core.sim.world import SceneEditError
from tasks import BasePose, BaseSubtask, TaskSequence
from tasks.sequence_file import EXAMPLES_DIR, load_sequence
from tests.app.bridge.conftest import wait_until
from tests.app.conftest import ROOT

NAV = load_sequence(EXAMPLES_DIR / "navigation_through_boxes.yaml")


def path_length(path: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if path is not None and len(path) > 1 else 0.0


@pytest.mark.slow
@pytest.mark.parametrize("map_kind", ["ground_truth", "object"])
def test_paper_navigation_through_a_random_scene(map_kind):
    rt = Runtime(RuntimeConfig(map_kind=map_kind), scene=random_scene(0), sequence=NAV)
    log = rt.run_lockstep(60.0)
    assert rt.run_state == RunState.FINISHED, rt.status_line()
    assert rt.world.collisions == []
    assert min(log.min_distance_m) > 0.0
    assert np.hypot(*(rt.state.q[:2] - [3.5, 0.0])) < 0.1 + 1e-6


@pytest.mark.slow
def test_box_moved_out_of_view_is_removed_and_the_path_gets_shorter():
    """A long box blocks the way and is mapped; then it is taken away to a place out of view while the
    cameras still look at where it stood. POCD removes it and the re-planned path goes straight."""
    scene = Scene((Box("blocker", (3.0, 0.0, 0.3), (0.6, 2.4, 0.6)),), robot_start=(0.0, 0.0, 0.0))
    goal = np.array([6.0, 0.0])
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=goal[0], y=goal[1]), timeout_s=60.0)])
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=scene, sequence=seq)
    rt.run_lockstep(1.0, until_done=False)
    assert rt.map.snapshot().objects, "the blocker was not mapped"
    detour = path_length(rt.sequencer.path)
    straight = float(np.linalg.norm(goal - rt.state.q[:2]))
    assert detour > straight + 0.5  # the first plan goes around the box
    rt.move_box("blocker", (3.0, 9.0, 0.3))
    ratios: list[float] = []

    def on_control(r: Runtime) -> None:
        remaining = float(np.linalg.norm(goal - r.state.q[:2]))
        if remaining > 1.0:
            ratios.append(path_length(r.sequencer.path) / remaining)

    log = rt.run_lockstep(40.0, on_control=on_control)
    snap = rt.map.snapshot()
    assert snap.removed_ids, "the moved box was never removed from the object map"
    assert all(np.linalg.norm(o.pose[:2, 3] - [3.0, 0.0]) > 0.5 for o in snap.objects)
    assert min(ratios) < 1.05  # re-planned straight once the phantom was gone
    assert rt.run_state == RunState.FINISHED and rt.world.collisions == []
    assert log.base_path_length_m() < detour - 0.3  # the robot drove a shorter route than first planned


def test_lockstep_is_deterministic_and_models_delays():
    scene = Scene((Box("a", (2.5, 1.2, 0.3)),))
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=3.0, y=0.0))])
    runs = []
    for delay in (0.0, 0.0, 0.2):
        rt = Runtime(RuntimeConfig(map_kind="ground_truth", actuation_delay_s=delay), scene=scene, sequence=seq)
        runs.append(np.array(rt.run_lockstep(2.0).q))
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.allclose(runs[0], runs[2])  # a modelled actuation delay changes the motion
    first_move = [int(np.argmax(np.abs(r[:, 0] - r[0, 0]) > 1e-3)) for r in runs]
    assert first_move[2] > first_move[0]


def _pushed_run(scene: Scene, seq: TaskSequence) -> np.ndarray:
    """q at every control step of an 8 s object-map run, box c pushed in view at the 30th step."""
    rt = Runtime(RuntimeConfig(map_kind="object", seed=4), scene=scene, sequence=seq)
    steps: list[np.ndarray] = []

    def on_control(r: Runtime) -> None:
        steps.append(r.state.q.copy())
        if len(steps) == 30:  # a push in view: the map registers it
            r.move_box("c", (3.75, 0.3, 0.3))

    rt.run_lockstep(8.0, on_control=on_control)
    return np.array(steps)


def test_lockstep_runs_through_the_whole_sensor_model_are_bit_identical():
    """Object map, depth cameras, drifting odometry, pushes registered: two runs of one seed give the same bits
    at every control step (experiments compare formulations on it; a test asserting a figure relies on it)."""
    scene = Scene((Box("a", (1.6, 0.9, 0.3)), Box("b", (1.6, -0.9, 0.3)), Box("c", (3.6, 0.2, 0.3))))
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=3.0, y=-0.4, yaw_deg=30.0))])
    runs = [_pushed_run(scene, seq) for _ in range(2)]
    assert runs[0].shape == runs[1].shape and len(runs[0]) > 50
    np.testing.assert_array_equal(runs[0], runs[1])


def test_bad_edits_are_refused_and_nothing_is_lost():
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=Scene((Box("a", (2.0, 0.0, 0.3)),)))
    with pytest.raises(SceneEditError, match="overlap the robot"):
        rt.add_box(Box("inside", (0.0, 0.0, 0.3)))
    with pytest.raises(SceneEditError, match="finite"):
        rt.move_box("a", (np.nan, 0.0, 0.3))
    assert [b.id for b in rt.scene().boxes] == ["a"]
    with pytest.raises(ValueError, match="map_kind"):
        RuntimeConfig(map_kind="octomap")


def _time_stands(snapshots, n: int = 5) -> bool:
    """The last `n` published snapshots show one sim time: the physics has stopped."""
    return len(snapshots) >= n and len({s.state.t for s in snapshots[-n:]}) == 1


@pytest.mark.wallclock
def test_live_run_control_and_subscribers():
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=2.0, y=0.0))])
    rt = Runtime(RuntimeConfig(map_kind="ground_truth", publish_hz=20.0), scene=Scene(), sequence=seq)
    got_a, got_b = [], []
    rt.subscribe(got_a.append)
    rt.subscribe(got_b.append)

    rt.start_live()
    try:
        rt.start()
        assert wait_until(lambda: rt.state.v[0] > 0.1, timeout_s=30)  # driving (a loaded machine starts slowly)
        rt.pause()
        assert wait_until(lambda: rt.run_state == RunState.PAUSED and _time_stands(got_a), timeout_s=30)
        t_paused = rt.time
        ten_more = len(got_a) + 10
        assert wait_until(lambda: len(got_a) >= ten_more, timeout_s=30)
        assert rt.time == pytest.approx(t_paused)  # physics frozen over ten more published snapshots
        rt.step()
        assert wait_until(lambda: rt.time > t_paused + 0.05 and _time_stands(got_a), timeout_s=30)
        assert rt.time == pytest.approx(t_paused + 0.1, abs=0.011)
        rt.start()
        assert wait_until(lambda: rt.time > t_paused + 0.3, timeout_s=30)
        rt.emergency_stop()
        assert wait_until(lambda: np.abs(rt.state.v).max() < 0.02, timeout_s=30)
        assert rt.run_state == RunState.ESTOP
        assert wait_until(lambda: any(s.run_state == RunState.ESTOP for s in got_a), timeout_s=30)  # published
    finally:
        rt.shutdown()
    assert len(got_a) > 20 and [s.seq for s in got_a] == [s.seq for s in got_b]


def test_recording_round_trip(tmp_path):
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=Scene((Box("a", (2.0, 0.5, 0.3)),)),
                 sequence=TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=3.5, y=-1.0))]))  # still driving at 3 s
    path = tmp_path / "run.mcap"
    rec = Recorder(path, points_every=2)
    rt.subscribe(rec)
    rt.run_lockstep(3.0, publish_every=2)
    rec.close()
    snaps = list(read_recording(path))
    assert len(snaps) == rec.count > 10
    last = snaps[-1]
    assert last.state.q.shape == (9,) and last.plan is not None and last.boxes[0].id == "a"
    assert last.object_map is not None and len(last.object_map.objects) >= 1
    assert [s.state.t for s in snaps] == sorted(s.state.t for s in snaps)
    bad = tmp_path / "bad.mcap"
    bad.write_text("something else")
    with pytest.raises(ValueError, match="not a studio recording"):
        read_recording(bad)
    old = tmp_path / "old.jsonl.gz"
    with gzip.open(old, "wt") as f:
        f.write(json.dumps({"format": "perceptive-htmpc-recording/1"}) + "\n")
    with pytest.raises(ValueError, match="old .jsonl.gz recording"):
        read_recording(old)


@pytest.mark.slow
def test_headless_cli_writes_a_report(tmp_path):
    out = tmp_path / "report"
    proc = subprocess.run([sys.executable, "-m", "app", "run", "--headless", "--map", "ground_truth", "--sequence",
                           str(EXAMPLES_DIR / "navigation_through_boxes.yaml"), "--max-duration", "60",
                           "--out", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    report = json.loads((out / "report.json").read_text())
    assert report["meta"]["outcome"] == "finished"
    assert report["summary"]["collisions"] == 0 and report["summary"]["base_path_length_m"] > 5.0
    assert (out / "path.png").stat().st_size > 10_000 and (out / "timeseries.png").stat().st_size > 10_000


def test_cli_bad_sequence_file_is_a_clear_error(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("subtasks:\n- kind: base\n  target: {x: .nan, y: 0}\n")
    proc = subprocess.run([sys.executable, "-m", "app", "run", "--headless", "--sequence", str(bad)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "line 3" in proc.stderr and "subtasks.0.target.x" in proc.stderr
