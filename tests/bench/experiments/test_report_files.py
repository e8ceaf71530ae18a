"""Reports name the commit their trials ran on: flagged when the code had uncommitted changes, kept when a
report is rewritten from saved trials."""

import argparse
import json

from bench.experiments.report_files import RunStamp, finish_experiment, write_json, write_markdown

DIRTY = RunStamp("abc1234+dirty", "2026-01-02T03:04:05Z", {"cpu": "Test CPU", "cores": 2})
CLEAN = RunStamp("def5678", "2026-01-02T03:04:05Z", {"cpu": "Test CPU", "cores": 2})


def test_a_dirty_run_is_flagged_in_json_and_markdown(tmp_path):
    write_json(tmp_path, "ex", {}, {"a": 1.0}, [{"seed": 0}], quick=False, stamp=DIRTY)
    assert json.loads((tmp_path / "ex.json").read_text())["commit"] == "abc1234+dirty"
    text = write_markdown(tmp_path, "ex", "Example", [("Body", "text")], quick=False).read_text()
    assert "`abc1234+dirty`, 2026-01-02 03:04 UTC, Test CPU (2 cores)" in text
    assert "uncommitted changes" in text


def test_report_only_keeps_the_runs_stamp(tmp_path, capsys):
    write_json(tmp_path, "ex", {}, {"a": 1.0}, [{"seed": 0}], quick=False, stamp=CLEAN)
    args = argparse.Namespace(out=tmp_path, quick=False, report_only=True)
    written = []
    figures = finish_experiment(args, "ex", [{"seed": 0}], {"a": 1.0, "b_mps_x": 2.0}, {"k": 1},
                                draw=lambda out: ["fig.png"], write=written.append, show=lambda k: "mps_" not in k)
    saved = json.loads((tmp_path / "ex.json").read_text())
    assert (saved["commit"], saved["when"], saved["machine"]) == (CLEAN.commit, CLEAN.when, CLEAN.machine)
    assert saved["settings"] == {"k": 1} and figures == {"a": 1.0, "b_mps_x": 2.0} and written == [["fig.png"]]
    assert capsys.readouterr().out.strip() == "a: 1.00"
    text = write_markdown(tmp_path, "ex", "Example", [], quick=False).read_text()
    assert "`def5678`" in text and "uncommitted" not in text


def test_the_params_file_a_run_used_is_kept_and_named_in_the_command(tmp_path):
    stamp = RunStamp("def5678", "2026-01-02T03:04:05Z", {"cpu": "Test CPU", "cores": 2}, "tunables.yaml")
    write_json(tmp_path, "ex", {}, {}, [], quick=False, stamp=stamp)
    assert RunStamp.saved(tmp_path, "ex").params_file == "tunables.yaml"
    text = write_markdown(tmp_path, "ex", "Example", [], quick=False).read_text()
    assert "`python -m bench.experiments.ex --params tunables.yaml`" in text
    write_json(tmp_path, "plain", {}, {}, [], quick=False, stamp=CLEAN)
    assert "--params" not in write_markdown(tmp_path, "plain", "Example", [], quick=False).read_text()


def test_a_run_is_stamped_with_the_commit_it_began_on_not_the_one_at_its_end(tmp_path):
    """A commit made while a long run goes on is not the run's: `finish_experiment` writes the stamp
    `experiment_args` took before the trials."""
    import argparse

    from bench.experiments.report_files import finish_experiment

    began = RunStamp("abc1234", "2026-01-02T03:04:05Z", {"cpu": "Test CPU", "cores": 2})
    args = argparse.Namespace(out=tmp_path, report_only=False, params=None, quick=False, stamp=began)
    finish_experiment(args, "ex", [], {}, {}, lambda out: [], lambda pngs: None)
    assert RunStamp.saved(tmp_path, "ex").commit == "abc1234"
