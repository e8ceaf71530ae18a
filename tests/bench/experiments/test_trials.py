"""The trial runner: order kept, crashes reported (never dropped), the same results in-process and on the pool."""

import math

import pytest

from bench.experiments.trials import Trial, experiment_args, run_trials


def square(params: dict) -> dict:
    if params["x"] < 0:
        raise ValueError("negative x")
    return {"y": params["x"] ** 2}


def test_results_in_order_with_params_and_wall_time():
    trials = [Trial(square, {"x": x}) for x in (3, 1, 2)]
    out = run_trials(trials, workers=1)
    assert [r["y"] for r in out] == [9, 1, 4]
    assert [r["x"] for r in out] == [3, 1, 2]
    assert all(r["wall_s"] >= 0.0 and math.isfinite(r["wall_s"]) for r in out)


def test_a_crashed_trial_is_kept_with_its_error():
    out = run_trials([Trial(square, {"x": 2}), Trial(square, {"x": -1})], workers=1)
    assert out[0]["y"] == 4 and "error" not in out[0]
    assert out[1]["error"] == "ValueError: negative x" and "y" not in out[1]


def test_process_pool_matches_in_process():
    trials = [Trial(square, {"x": x}) for x in range(-1, 5)]
    strip = [{k: v for k, v in r.items() if k not in ("wall_s", "traceback")} for r in run_trials(trials, workers=1)]
    pooled = [{k: v for k, v in r.items() if k not in ("wall_s", "traceback")} for r in run_trials(trials, workers=2)]
    assert pooled == strip


@pytest.mark.slow
def test_trials_run_on_a_local_ray_cluster():
    """`--ray local` starts a one-machine Ray cluster, ships this checkout and runs every trial there."""
    pytest.importorskip("ray", reason="ray comes with the dev extra")
    trials = [Trial(dict, {"x": x}) for x in (3, 1, 2)]  # dict(params) == params: a trial Ray can import
    out = run_trials(trials, ray_address="local")
    assert [r["x"] for r in out] == [3, 1, 2] and not any("error" in r for r in out)


def test_command_line_defaults_and_bad_workers(tmp_path):
    args = experiment_args("e0", "test", ["--quick", "--out", str(tmp_path)])
    assert args.quick and args.workers == 2 and args.ray is None and args.out == tmp_path
    with pytest.raises(SystemExit):
        experiment_args("e0", "test", ["--workers", "0"])
