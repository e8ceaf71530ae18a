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


# Measurements of the process that ran a trial, not results of the trial: they differ between runners.
PER_PROCESS = ("wall_s", "traceback", "worker_rss_gb")


def test_process_pool_matches_in_process():
    trials = [Trial(square, {"x": x}) for x in range(-1, 5)]
    inline = run_trials(trials, workers=1)
    pooled = run_trials(trials, workers=2)
    assert [_results(r) for r in pooled] == [_results(r) for r in inline]


def test_each_result_records_its_workers_memory():
    """`worker_rss_gb` lets a long sweep show whether its workers grow (the full E2 once reached 9 GB each)."""
    for runner_workers in (1, 2):
        out = run_trials([Trial(square, {"x": x}) for x in range(3)], workers=runner_workers)
        assert all(0.0 < r["worker_rss_gb"] < 100.0 for r in out)


def _results(result: dict) -> dict:
    return {k: v for k, v in result.items() if k not in PER_PROCESS}


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


def tuned_gamma(params: dict) -> dict:
    from bench.experiments.trials import runtime_config, tunables

    return {"gamma": tunables().htmpc.gamma, "config_gamma": runtime_config(map_kind="voxel").htmpc.gamma}


@pytest.fixture
def default_tunables_after():
    yield
    experiment_args("e0", "test", [])  # back to the defaults in this process


def test_params_file_reaches_the_trials_in_every_worker(tmp_path, default_tunables_after):
    from bench.experiments.trials import trial_results

    params = tmp_path / "p.yaml"
    params.write_text("htmpc: {gamma: 0.25}\n")
    args = experiment_args("e0", "test", ["--params", str(params), "--workers", "2", "--out", str(tmp_path)])
    trials = [Trial(tuned_gamma, {"i": i}) for i in range(3)]
    for workers in (1, 2):
        args.workers = workers
        out = trial_results(args, "e0", trials, "tuned")
        assert [(r["gamma"], r["config_gamma"]) for r in out] == [(0.25, 0.25)] * 3


def test_bad_params_file_stops_the_experiment_with_field_and_line(tmp_path, capsys):
    params = tmp_path / "p.yaml"
    params.write_text("htmpc:\n  gamma: -1\n")
    with pytest.raises(SystemExit):
        experiment_args("e0", "test", ["--params", str(params)])
    assert "line 2: htmpc.gamma" in capsys.readouterr().err
