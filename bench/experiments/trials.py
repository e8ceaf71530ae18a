"""Running independent trials: in this process, on a local process pool (default) or on a Ray cluster.

A trial is a top-level function of one plain `dict` of parameters returning a JSON-able `dict`;
it builds its runtime with `runtime_config(...)`, which starts from the tunables of `--params FILE.yaml`
(core/params_file.py; shipped to each worker with its trial), then applies what the experiment varies;
`run_trials` calls it for every parameter set with a progress bar and returns the results in the
order given, each merged with its parameters, `wall_s` and, when it raised, `error` (a crashed
trial is reported, never dropped and never counted as a success).

Workers are started with `spawn` (MuJoCo's GL contexts and casadi do not survive a fork) and with
one BLAS/OpenMP thread each, so N workers use N cores. Ray is an optional extra
(`pip install -e '.[ray]'`); it is imported only when `--ray ADDRESS` is given.
"""

from __future__ import annotations

import argparse
import gc
import json
import logging
import math
import os
import sys
import time
import traceback
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from multiprocessing import get_context
from pathlib import Path

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

import core.sim  # noqa: F401  (chooses the GL backend once; spawned workers inherit MUJOCO_GL)
from bench.experiments.paths import REPORTS_DIR, ROOT
from core.params import HTMPCParams
from core.params_file import Tunables, load_params
from core.yaml_validation import FileFormatError

log = logging.getLogger(__name__)

RAY_EXCLUDES = [".venv", ".git", "reports", "test-artifacts", "bench/results", "runs", "*.egg-info"]
SINGLE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

TrialFn = Callable[[dict], dict]


@dataclass(frozen=True)
class Trial:
    """One independent run: `fn(params)`; `fn` must be a module-level function (it is pickled by name).
    `tunables` (from `--params`) are in force while it runs (`tunables()`, `runtime_config`)."""

    fn: TrialFn
    params: dict = field(default_factory=dict)
    tunables: Tunables | None = None


PAPER_TUNABLES = Tunables(htmpc=replace(HTMPCParams(), control_on_new_map=False))
"""The experiments' defaults: the paper's periodic 10 Hz control step (a step on each new map is our addition,
`HTMPCParams.control_on_new_map`); a `--params` file's values go over these."""
_tunables = PAPER_TUNABLES


def tunables() -> Tunables:
    """The tunables of the trial running in this process (defaults unless `--params` gave a file)."""
    return _tunables


def runtime_config(**kwargs):
    """`app.runtime.RuntimeConfig` with the trial's tunables; `kwargs` (what the experiment varies) win."""
    from app.runtime import RuntimeConfig

    return RuntimeConfig(**{**tunables().sections(), **kwargs})


def experiment_args(name: str, description: str, argv: list[str] | None = None,
                    extra: Callable[[argparse.ArgumentParser], None] | None = None) -> argparse.Namespace:
    """The command line every experiment shares (`extra` adds an experiment's own options)."""
    parser = argparse.ArgumentParser(prog=f"python -m bench.experiments.{name}", description=description)
    parser.add_argument("--quick", action="store_true", help="smoke variant: a few short trials (1–2 minutes)")
    parser.add_argument("--workers", type=int, default=2, help="local worker processes (1: run in this process)")
    parser.add_argument("--ray", metavar="ADDRESS", default=None,
                        help="run the trials on a Ray cluster at ADDRESS ('auto', 'ray://host:10001', 'local')")
    parser.add_argument("--out", type=Path, default=REPORTS_DIR / name, help="report folder")
    parser.add_argument("--report-only", action="store_true",
                        help="no trials: rebuild figures and report from the JSON of the last run in --out")
    parser.add_argument("--params", type=Path, default=None, metavar="FILE.yaml",
                        help="tunables overriding core/params.py (the experiment's own settings still apply)")
    if extra is not None:
        extra(parser)
    args = parser.parse_args(argv if argv is not None else sys.argv[1:])
    if args.workers < 1:
        parser.error("--workers must be at least 1")
    try:
        args.tunables = load_params(args.params, PAPER_TUNABLES) if args.params else None
    except FileFormatError as err:
        parser.error(str(err))
    _use(args.tunables)  # in force here too (summaries), and shipped with each trial to the workers
    # the commit the trials run on is HEAD now: a commit made while a long run goes on is not the run's
    from bench.experiments.report_files import RunStamp  # (matplotlib with it: not in the trials' workers)

    args.stamp = None if args.report_only else RunStamp.now(str(args.params) if args.params else None)
    return args


def _use(tuned: Tunables | None) -> None:
    global _tunables
    _tunables = tuned or PAPER_TUNABLES


QUIET_LOGGERS = ("core.htmpc", "tasks.sequencer", "app.runtime")
"""Per-step warnings of these (a fallback plan, a failed subtask) are counted in the results; printed they
would bury the progress bar."""


def quiet_logs() -> None:
    """Warnings from the closed loop's per-step loggers are not printed (they are in the trial results)."""
    logging.basicConfig(level=logging.WARNING)
    for name in QUIET_LOGGERS:
        logging.getLogger(name).setLevel(logging.ERROR)


def load_trials(out_dir: Path, name: str, quick: bool) -> list[dict]:
    """The trials of the last run saved in `<out_dir>/<name>.json` (for `--report-only`); NaN where it has null."""
    path = out_dir / f"{name}.json"
    if not path.exists():
        raise SystemExit(f"--report-only: no earlier run at {path}; run the experiment without it first")
    data = json.loads(path.read_text(encoding="utf-8"))
    if bool(data.get("quick")) != quick:
        raise SystemExit(f"--report-only: the run saved at {path} was{'' if data.get('quick') else ' not'} --quick; "
                         "pass the same option")
    return [{k: (math.nan if v is None else v) for k, v in t.items()} for t in data["trials"]]


def trial_results(args: argparse.Namespace, name: str, trials: list[Trial], description: str) -> list[dict]:
    """The experiment's results: its trials run now, or with `--report-only` those of the saved run."""
    if args.report_only:
        return load_trials(args.out, name, args.quick)
    tuned = getattr(args, "tunables", None)
    return run_trials([replace(t, tunables=tuned) for t in trials], args.workers, args.ray, description)


def run_one(trial: Trial) -> dict:
    """Run a trial, catching its failure: the result carries the parameters, `wall_s` and any `error`."""
    _use(trial.tunables)
    t0 = time.perf_counter()
    try:
        out = trial.fn(dict(trial.params))
    except Exception as err:  # a crashed trial is a result to report, not a reason to lose the sweep
        log.exception("trial %s failed", trial.params)
        out = {"error": f"{type(err).__name__}: {err}", "traceback": traceback.format_exc(limit=8)}
    wall_s = time.perf_counter() - t0
    # A finished run's reference cycles hold its maps and frames until a full collection: without this the
    # full E2 grew each pool worker to 9 GB in 28 minutes. (Replacing workers with `max_tasks_per_child`
    # is no way out on Python 3.11: the pool hung once its first workers retired.)
    gc.collect()
    return {**trial.params, **out, "wall_s": wall_s, "worker_rss_gb": _rss_gb()}


def _rss_gb() -> float:
    """This process's resident memory (GB; NaN where /proc is missing)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, IndexError, ValueError):
        return math.nan
    return pages * os.sysconf("SC_PAGE_SIZE") / 1e9


def run_trials(trials: list[Trial], workers: int = 2, ray_address: str | None = None,
               description: str = "trials") -> list[dict]:
    """Run every trial (pool, Ray or in-process) with a progress bar; results in the order of `trials`."""
    if not trials:
        return []
    if ray_address:
        runner = _on_ray(trials, ray_address)
    elif workers > 1 and len(trials) > 1:
        runner = _on_pool(trials, workers)
    else:
        runner = ((i, run_one(t)) for i, t in enumerate(trials))
    results: list[dict | None] = [None] * len(trials)
    with _progress() as bar:
        task = bar.add_task(description, total=len(trials))
        for index, result in runner:
            results[index] = result
            bar.advance(task)
    failed = sum("error" in r for r in results if r is not None)
    if failed:
        log.warning("%d of %d trials raised an error (kept in the results)", failed, len(trials))
    return [r for r in results if r is not None]


def _progress() -> Progress:
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    TextColumn("eta"), TimeRemainingColumn())


def _on_pool(trials: list[Trial], workers: int) -> Iterator[tuple[int, dict]]:
    """A spawn-context process pool; yields (index, result) as trials finish."""
    for key, value in SINGLE_THREAD_ENV.items():
        os.environ.setdefault(key, value)  # inherited by the spawned workers
    with ProcessPoolExecutor(max_workers=min(workers, len(trials)), mp_context=get_context("spawn"),
                             initializer=quiet_logs) as pool:
        futures = {pool.submit(run_one, t): i for i, t in enumerate(trials)}
        for future in as_completed(futures):
            yield futures[future], future.result()


def _run_one_quiet(trial: Trial) -> dict:
    quiet_logs()
    return run_one(trial)


def _import_ray():
    try:
        import ray
    except ImportError as err:
        raise SystemExit("--ray needs the optional dependency ray: install the project's extra with "
                         "`pip install -e '.[ray]'` (ray[default]>=2.9), or drop --ray to use local workers") from err
    return ray


def _on_ray(trials: list[Trial], address: str) -> Iterator[tuple[int, dict]]:
    """Ship this checkout as the job's working dir and run one trial per Ray task (1 CPU each)."""
    ray = _import_ray()
    env = {"working_dir": str(ROOT), "excludes": RAY_EXCLUDES, "env_vars": dict(SINGLE_THREAD_ENV)}
    ray.init(address=address, runtime_env=env, ignore_reinit_error=True, log_to_driver=False)
    remote = ray.remote(num_cpus=1)(_run_one_quiet)
    refs = {remote.remote(t): i for i, t in enumerate(trials)}
    pending = list(refs)
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                yield refs[ref], ray.get(ref)
    finally:
        ray.shutdown()
