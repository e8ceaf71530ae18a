"""The command line: --params reaches every part of the runtime, bad files and unacceptable targets are clear
errors (field and line) before anything runs."""

import json
import subprocess
import sys

import pytest

from app.cli import _config, build_parser
from app.runtime import ProblemKind
from tasks.sequence_file import EXAMPLES_DIR
from tests.app.conftest import ROOT

NAV = str(EXAMPLES_DIR / "navigation_through_boxes.yaml")


def run_cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "app", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def test_params_file_sets_the_runtime_config(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("htmpc: {gamma: 0.5, constraint: edf}\nsim:\n  hand_camera: {range_m: 2.0}\n"
                    "robot: {base_speed_mps: 0.7}\nmapping: {tau_m: 0.3}\nsequencer: {nominal_speed_mps: 0.4}\n")
    config = _config(build_parser().parse_args(["run", "--headless", "--sequence", NAV, "--params", str(path)]))
    assert (config.htmpc.gamma, config.constraint, config.sim.hand_camera.range_m) == (0.5, "edf", 2.0)
    assert (config.robot.base_speed_mps, config.mapping.tau_m, config.sequencer.nominal_speed_mps) == (0.7, 0.3, 0.4)
    explicit = _config(build_parser().parse_args(["run", "--headless", "--sequence", NAV, "--params", str(path),
                                                  "--constraint", "cbf"]))
    assert explicit.constraint == "cbf"  # the command line wins over the file


def test_bad_params_file_names_field_and_line(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("htmpc:\n  gamma: 0.5\n  delta_safe: 0.3\n")
    proc = run_cli("run", "--headless", "--sequence", NAV, "--params", str(path), timeout=120)
    assert proc.returncode == 2
    assert "line 3" in proc.stderr and "htmpc.delta_safe" in proc.stderr


def test_targets_the_robot_cannot_take_are_refused_before_the_run(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"scene: {ROOT / 'core/scenes/default.yaml'}\nsubtasks:\n- kind: base\n"
                   "  target: {x: 2.2, y: 1.3}\n- kind: ee\n  target: {position: [2.0, 0.0, 5.0]}\n")
    proc = run_cli("run", "--headless", "--sequence", str(bad), timeout=180)
    assert proc.returncode == 2
    assert "line 4: subtasks.0.target" in proc.stderr and "inside box_a" in proc.stderr
    assert "line 6: subtasks.1.target" in proc.stderr and "nearest acceptable: (2.00, 0.00," in proc.stderr


def test_a_goal_in_a_closed_pen_is_refused_before_the_run(tmp_path):
    """The scene is known (simulation): a base goal no path reaches from the robot's start is refused with exit 2,
    naming the box that closes it in and the nearest reachable place (it used to time out after 60 s)."""
    from tests.app.test_no_path import pen_scene

    boxes = "".join(f"- {{id: {b.id}, position: [{b.position[0]:.2f}, {b.position[1]:.2f}, 0.3]}}\n"
                    for b in pen_scene().boxes)
    (tmp_path / "pen.yaml").write_text(f"robot_start: [0.0, 0.0, 0.0]\nboxes:\n{boxes}")
    seq = tmp_path / "into_the_pen.yaml"
    seq.write_text("scene: pen.yaml\nsubtasks:\n- kind: base\n  target: {x: 4.0, y: 0.0}\n")
    proc = run_cli("run", "--sequence", str(seq), timeout=180)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert f"{seq}: 1 problem\n" in proc.stderr
    assert "line 4: subtasks.0.target" in proc.stderr and "no path reaches it from (0.00, 0.00)" in proc.stderr
    assert "nearest pen_" in proc.stderr and "nearest acceptable: (" in proc.stderr


def test_a_failed_run_says_so_once_with_what_failed_it(tmp_path):
    """Exit 1 and one line 'failed: <subtask>: timed out …' (it read 'failed: failed: …'), the bar at 100 %."""
    seq = tmp_path / "short.yaml"
    seq.write_text(f"scene: {ROOT / 'core/scenes/default.yaml'}\nsubtasks:\n- name: too far for 1 s\n  kind: base\n"
                   "  target: {x: 1.5, y: -0.2, yaw_deg: 90}\n  timeout_s: 1.0\n")
    proc = run_cli("run", "--map", "ground_truth", "--sequence", str(seq), "--out", str(tmp_path / "out"))
    assert proc.returncode == 1, proc.stderr[-2000:]
    line = next(x for x in proc.stdout.splitlines() if x.startswith("failed"))
    assert line.startswith("failed: too far for 1 s: timed out after 1 s (") and "failed: failed" not in line
    assert "° from the goal)" in line
    assert "100%" in proc.stdout


@pytest.mark.slow
def test_headless_run_with_params_reports_them(tmp_path):
    params = tmp_path / "p.yaml"
    params.write_text("sequencer: {nominal_speed_mps: 0.8}\nhtmpc: {gamma: 2.0}\n")
    out = tmp_path / "report"
    proc = run_cli("run", "--map", "ground_truth", "--sequence", NAV, "--params", str(params),  # headless by default
                   "--max-duration", "60", "--out", str(out))
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "100%" in proc.stdout  # the bar ends full when the sequence finishes before --max-duration
    report = json.loads((out / "report.json").read_text())
    assert report["meta"]["tunables"]["htmpc"]["gamma"] == 2.0
    assert report["meta"]["tunables"]["sequencer"]["nominal_speed_mps"] == 0.8
    assert report["summary"]["max_base_speed_mps"] > 0.8  # 0.65 m/s with the default 0.6 m/s reference
    assert "problems" in report and "problems:" in proc.stdout
    assert set(report["problems"]) == {kind.value for kind in ProblemKind}  # every kind, zeros too
    assert all(isinstance(row["count"], int) for row in report["problems"].values())


def test_help_shows_defaults_units_and_exit_codes():
    proc = run_cli("run", "--help", timeout=60)
    assert proc.returncode == 0
    text = " ".join(proc.stdout.split())
    assert "--max-duration S sim time at most (s) (default: 300.0)" in text
    assert "two_pickups.yaml" in text and "(default: object)" in text
    assert "--perception-delay S modelled delay (s)" in text and "(default: 0.0)" in text
    assert "exit codes: 0" in text and "3 the run faulted" in text
    assert "--headless accepted for older scripts" in text
