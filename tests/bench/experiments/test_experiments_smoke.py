"""Smoke variants (`--quick`) of the four experiments: real closed loops in lockstep, reports written.

Each asserts the paper's qualitative claim on its few trials (lockstep runs are deterministic), and
that the report has JSON, figures and the markdown with the paper's figures beside ours.
"""

import json

import pytest

from bench.experiments import e1_object_vs_voxel, e2_cbf_vs_edf, e3_reactive, e4_long_term

pytestmark = pytest.mark.slow


def _report(out, name: str) -> dict:
    data = json.loads((out / f"{name}.json").read_text())
    assert data["quick"] is True and data["trials"] and not data["errors"]
    markdown = (out / "README.md").read_text()
    assert "paper" in markdown.lower() and "--quick" in markdown
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs and all(f"({p})" in markdown for p in pngs)
    return data


def test_e1_object_map_forgets_boxes_moved_out_of_view_voxel_map_keeps_them(tmp_path):
    f = e1_object_vs_voxel.main(["--quick", "--out", str(tmp_path)])
    _report(tmp_path, "e1_object_vs_voxel")
    assert f["object_moved_boxes"] >= 2 and f["voxel_moved_boxes"] >= 2  # the same unseen move with each map
    assert f["object_phantoms_at_end_mean"] == 0 and f["voxel_phantoms_at_end_mean"] >= 1
    assert f["object_leg2_success_rate"] == f["voxel_leg2_success_rate"] == 1.0
    assert f["object_leg2_path_m_median"] < f["voxel_leg2_path_m_median"]  # the phantom forces a detour
    assert f["object_collision_free_rate"] == f["voxel_collision_free_rate"] == 1.0


def test_e2_cbf_keeps_more_clearance_than_edf_and_gamma_orders_it(tmp_path):
    f = e2_cbf_vs_edf.main(["--quick", "--out", str(tmp_path)])
    data = _report(tmp_path, "e2_cbf_vs_edf")
    assert len(data["trials"]) == 10  # 1 scene × 1 speed × 4 map conditions × 2 constraints + 2 gammas
    for m in ("ground_truth", "object", "object_surface", "object_delayed"):
        for c in ("cbf", "edf"):
            assert f[f"{m}_{c}_success"] == f[f"{m}_{c}_collision_free"] == 1.0
    for m in ("object", "object_surface", "object_delayed"):  # perceived through the sensor model
        assert f[f"{m}_cbf_min_clearance_m_median"] > f[f"{m}_edf_min_clearance_m_median"]
    # one scene through the sensor model: the sweep's order shows over the full run's 15 scenes only
    assert f["gamma_0.5_collision_free"] == f["gamma_4_collision_free"] == 1.0


def test_e3_a_box_pushed_too_close_is_hit_one_further_away_is_avoided(tmp_path):
    f = e3_reactive.main(["--quick", "--out", str(tmp_path)])
    data = _report(tmp_path, "e3_reactive")
    for body in ("base", "ee"):
        # 0.5 m ahead at 1 m/s with 0.5 s closed-loop delay is inside the 0.75 m stopping distance
        assert f[f"object_{body}_max_collided_m"] == 0.5
        assert f[f"object_{body}_min_avoided_m"] == 1.5
    assert f["stop_distance_with_delay_m"] == pytest.approx(0.75)
    # at our own latency (a control step on each new map) the bound is 0.46 m: the hand avoids the 0.5 m push;
    # the base, sidestepping, grazed it by 0.8 mm since the arm holds a joint posture while the base drives
    # (2026-11-27; before: avoided): within 1.3x the bound, what the latency issue asks, but not clear of it
    assert f["braking_bound_own_latency_m"] < 0.5
    assert f["object_ee_min_avoided_own_latency_m"] == 0.5
    own = [t for t in data["trials"] if t["part"] == "sweep" and t["map"] == "object_own_latency"]
    assert all(t["collision_free"] for t in own if t["d"] > 1.3 * f["braking_bound_own_latency_m"])
    assert max(t["max_penetration_m"] for t in own) < 0.005
    for t in data["trials"]:
        if t["part"] == "random":
            assert t["pushed"] == t["n"], "every box was pushed in front of the robot"


def test_e4_a_lap_with_two_picks_while_boxes_are_rearranged(tmp_path):
    f = e4_long_term.main(["--quick", "--out", str(tmp_path)])
    _report(tmp_path, "e4_long_term")
    # Through the whole sensor model, the camera latency compensated (without it the walls seen in the
    # turns are smeared and the corridor closes: object 4/5, voxel 2/5, measured 2026-11-23)
    for m in ("object", "voxel"):
        assert f[f"laps_{m}_subtasks"] == 5 and f[f"laps_{m}_collision_events"] == 0
    assert f["laps_object_completed"] == 5 and f["laps_voxel_completed"] >= 4  # both 5 measured
