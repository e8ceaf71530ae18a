"""Command line of the studio.

    python -m app [serve] [options]     serve the studio (default)
    python -m app run ...               run a sequence headless in lockstep and write a report (JSON + plots);
                                        exit 0 finished, 1 not finished, 2 bad input, 3 fault
    python -m app replay FILE           replay a recorded run in the studio
    python -m app recording repair FILE give a recording torn by a crash its summary again
"""

from __future__ import annotations

import argparse
import datetime as dt
import logging
import signal
import sys
import threading
from dataclasses import asdict as dt_asdict
from pathlib import Path
from typing import TYPE_CHECKING

from app.runtime import CONSTRAINT_KINDS, DEFAULT_SCENE, DEFAULT_SEQUENCE, MAP_KINDS, ROOT, RuntimeConfig

if TYPE_CHECKING:
    from app.recording import Recorder

EXIT_FAULT = 3
"""`run`: the run faulted (the robot braked to rest; the reason is the last line on stderr)."""
EXIT_CODES = """exit codes:
  0  served and stopped with Ctrl+C (serve, replay); the sequence finished (run)
  1  the sequence did not finish: a subtask failed or --max-duration ran out (run)
  2  bad input: a file, a tunable or a target refused, with its line, field and nearest acceptable value
  3  the run faulted: the robot braked to rest; the reason is the last line on stderr (run)"""


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Help that shows every default (unless the text already says it, or there is none to show: a flag, None)
    and keeps the exit-code table's lines."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "default" in text or action.default is None or action.default is False or \
                action.default == argparse.SUPPRESS or not action.option_strings:
            return text
        return text + " (default: %(default)s)"


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scene", type=Path, default=None,
                        help="scene YAML (default: the sequence's scene, else core/scenes/default.yaml)")
    parser.add_argument("--sequence", type=Path, default=DEFAULT_SEQUENCE, help="task sequence YAML")
    parser.add_argument("--map", dest="map_kind", choices=MAP_KINDS, default="object",
                        help="map the controller uses (object: POCD, voxel: the static baseline, ground_truth: the "
                             "simulator's exact boxes)")
    parser.add_argument("--constraint", choices=CONSTRAINT_KINDS, default=None,
                        help="collision constraint kind (default: the --params file's, else cbf)")
    parser.add_argument("--params", type=Path, default=None, metavar="FILE.yaml",
                        help="tunables over the app's defaults (core/params.py with localization on), by section "
                             "(htmpc: {gamma: 0.5}, localization: {enabled: false}, ...)")
    parser.add_argument("--scene-may-change", action="store_true",
                        help="accept targets too close to today's boxes with a warning (the boxes move first)")
    parser.add_argument("--log-level", default="INFO", help="DEBUG, INFO, WARNING or ERROR")
    parser.add_argument("--record", type=Path, default=None,
                        help="record the run to this MCAP file (.mcap; replay with `python -m app replay FILE`)")
    parser.add_argument("--record-depth", action="store_true",
                        help="with --record: keep the depth frames too (about 0.2 MB a frame)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m app", description="Perceptive HTMPC Studio",
                                     epilog=EXIT_CODES, formatter_class=HelpFormatter)
    sub = parser.add_subparsers(dest="command")
    serve = sub.add_parser("serve", help="serve the studio (default)", epilog=EXIT_CODES, formatter_class=HelpFormatter)
    _common(serve)
    serve.add_argument("--host", default="127.0.0.1",
                       help="address to serve on (default: this machine only; any other address, or --backend "
                            "bridge, makes the page need the access link printed at start)")
    serve.add_argument("--port", type=int, default=8080, help="port of the studio page")
    serve.add_argument("--speed", type=float, default=1.0, help="sim seconds per wall second (×)")
    serve.add_argument("--backend", choices=("sim", "bridge"), default="sim",
                       help="sim: embedded MuJoCo; bridge: a robot driver connected to the hardware bridge")
    serve.add_argument("--bridge-port", type=int, default=8090, help="port of the hardware bridge (--backend bridge)")
    serve.add_argument("--bridge-host", default="127.0.0.1", help="address of the hardware bridge (--backend bridge)")
    serve.add_argument("--foxglove", nargs="?", type=int, const=8765, default=None, metavar="PORT",
                       help="also serve the live run to Foxglove (WebSocket protocol) on --host, port 8765 or PORT")
    run = sub.add_parser("run", help="run a sequence headless in lockstep and write a report", epilog=EXIT_CODES,
                         formatter_class=HelpFormatter,
                         description="Run a sequence headless (no browser) in simulated time, as fast as the machine "
                                     "allows (deterministic), and write report.json, path.png and timeseries.png.")
    _common(run)
    run.add_argument("--headless", action="store_true",
                     help="accepted for older scripts: `run` is always headless")
    run.add_argument("--max-duration", type=float, default=300.0, metavar="S", help="sim time at most (s)")
    run.add_argument("--out", type=Path, default=None, help="report folder (default: runs/<date-time>)")
    run.add_argument("--perception-delay", type=float, default=0.0, metavar="S",
                     help="modelled delay (s) from a depth frame to the map using it")
    run.add_argument("--actuation-delay", type=float, default=0.0, metavar="S",
                     help="modelled delay (s) from a plan to the robot acting on it")
    replay = sub.add_parser("replay", help="replay a recorded run in the studio", epilog=EXIT_CODES,
                            formatter_class=HelpFormatter)
    replay.add_argument("file", type=Path, help="a recording (.mcap) written with --record")
    replay.add_argument("--host", default="127.0.0.1", help="address to serve on")
    replay.add_argument("--port", type=int, default=8080, help="port of the studio page")
    replay.add_argument("--log-level", default="INFO", help="DEBUG, INFO, WARNING or ERROR")
    recording = sub.add_parser("recording", help="tools for recordings", epilog=EXIT_CODES,
                               formatter_class=HelpFormatter)
    recording_sub = recording.add_subparsers(dest="action", required=True)
    repair = recording_sub.add_parser("repair", help="rewrite the summary of a recording torn by a crash",
                                      formatter_class=HelpFormatter)
    repair.add_argument("file", type=Path, help="a recording (.mcap) whose writer was killed")
    repair.add_argument("--log-level", default="INFO", help="DEBUG, INFO, WARNING or ERROR")
    return parser


def _scene_for(args) -> Path:
    if args.scene is not None:
        return args.scene
    from tasks.sequence_file import load_sequence

    seq = load_sequence(args.sequence)
    if seq.scene:
        return (args.sequence.parent / seq.scene).resolve()
    return DEFAULT_SCENE


def _recorder(args, robot, sim_time: bool = False) -> Recorder | None:
    """The MCAP recorder that --record asks for, else None; `sim_time`: log times in simulation time."""
    if not args.record:
        return None
    from app.recording import Recorder

    return Recorder(args.record, depth_frames=args.record_depth, sim_time=sim_time, robot=robot)
def _config(args, **extra) -> RuntimeConfig:
    """The runtime's configuration: scene, sequence, map, constraint and the tunables of --params."""
    from app.launch_defaults import launch_tunables

    tunables = launch_tunables(args.params)
    config = RuntimeConfig(scene=_scene_for(args), sequence=args.sequence, **tunables.sections(), **extra)
    return config.configured(map_kind=args.map_kind, constraint=args.constraint)


def _check_targets(runtime, args) -> None:
    """The sequence's targets in the runtime's scene (`tasks.validation`): refusals raise, warnings are printed."""
    from app.target_check import check_targets

    text = args.sequence.read_text(encoding="utf-8")
    for warning in check_targets(runtime, runtime.sequence, scene_may_change=args.scene_may_change,
                                 source=str(args.sequence), text=text):
        print(f"warning: {warning}", file=sys.stderr)


def _wait_for_signal() -> None:
    done = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: done.set())
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    done.wait()


def serve(args) -> int:
    from app.runtime import Runtime
    from app.ui.studio import Studio

    config = _config(args, speed=args.speed)
    backend, bridge = None, None
    if args.backend == "bridge":
        from app.bridge.server import BridgeServer

        if args.speed != 1.0:
            raise ValueError("--speed applies to the simulation; a real robot runs in real time")
        if args.map_kind == "ground_truth":
            raise ValueError("--map ground_truth needs the simulation; use object or voxel with --backend bridge")
        bridge = BridgeServer(port=args.bridge_port, host=args.bridge_host)
        bridge.start()
        backend = bridge.robot
        print(f"hardware bridge on {bridge.url} ({bridge.token_info.describe()})", flush=True)
    runtime = Runtime(config, backend=backend)
    try:
        _check_targets(runtime, args)
    except ValueError:
        if bridge is not None:
            bridge.stop()
        raise
    if bridge is not None:
        bridge.attach(runtime)
    studio = Studio(runtime, host=args.host, port=args.port, require_token=bridge is not None)
    recorder = _recorder(args, runtime.robot)
    if recorder is not None:
        runtime.subscribe(recorder)
    live = _foxglove(args, runtime)
    runtime.start_live()
    print(f"Perceptive HTMPC Studio: open {studio.url} in a browser (Ctrl+C to quit)", flush=True)
    _wait_for_signal()
    runtime.shutdown()
    studio.close()
    if live is not None:
        live.close()
    if recorder is not None:
        recorder.close()
    if bridge is not None:
        bridge.stop()
    return 0


def _foxglove(args, runtime):
    """The Foxglove live server --foxglove asks for (subscribed to the runtime), else None."""
    if args.foxglove is None:
        return None
    from app.foxglove_access import serve_foxglove

    live = serve_foxglove(args.host, args.foxglove, require_token=args.backend == "bridge", robot=runtime.robot)
    runtime.subscribe(live)
    print(f"Foxglove: open a Foxglove WebSocket connection to {live.url} (layout: docs/foxglove_layout.json)",
          flush=True)
    return live


def repair_recording(args) -> int:
    from app.recording.repair import repair

    print(repair(args.file))
    return 0


def run_headless(args) -> int:
    from app.recording.report import write_report
    from app.runtime import Runtime
    from app.runtime.problems import summary_line

    config = _config(args, perception_delay_s=args.perception_delay, actuation_delay_s=args.actuation_delay)
    runtime = Runtime(config)
    _check_targets(runtime, args)
    recorder = _recorder(args, runtime.robot, sim_time=True)
    if recorder is not None:
        runtime.subscribe(recorder)
    from rich.progress import Progress

    with Progress() as progress:
        task = progress.add_task("lockstep run", total=args.max_duration)
        runtime.run_lockstep(args.max_duration, publish_every=1 if recorder else 0,
                             on_control=lambda rt: progress.update(task, completed=rt.time))
        # the run is over (finished early, failed or out of time): the bar says so, full
        progress.update(task, completed=args.max_duration, description=f"lockstep run: {runtime.run_state.value}")
    if recorder is not None:
        recorder.close()
        print(f"recording written to {args.record} ({recorder.count} snapshots)")
    out = args.out or ROOT / "runs" / dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    meta = {"title": runtime.sequence.name, "sequence": str(args.sequence), "scene": str(config.scene),
            "map": args.map_kind, "constraint": config.constraint, "params": str(args.params or ""),
            "tunables": {name: dt_asdict(getattr(config, name)) for name in ("robot", "sim", "htmpc", "mapping",
                                                                             "sequencer")},
            "outcome": runtime.run_state.value,
            "status": runtime.status_line(), "subtasks_done": sum(p.outcome.value == "done"
                                                                   for p in runtime.sequencer.progress),
            "fault": runtime.fault}
    summary = write_report(out, runtime.log, runtime.require_world().obstacles(), meta, runtime.problems)
    state, line = runtime.run_state.value, runtime.status_line()
    print(line if line.startswith(f"{state}:") else f"{state}: {line}")  # never 'failed: failed: …'
    print(f"problems: {summary_line(runtime.problems.counts())}")
    for key, value in summary.items():
        print(f"  {key}: {value:.3f}" if isinstance(value, float) else f"  {key}: {value}")
    print(f"report written to {out}")
    if runtime.fault is not None:
        print(f"fault: {runtime.fault}", file=sys.stderr)
        return EXIT_FAULT
    return 0 if runtime.run_state.value == "finished" else 1


def replay(args) -> int:
    from app.recording.replay import ReplaySource
    from app.ui.studio import Studio

    source = ReplaySource(args.file)
    print(source.recording.report, flush=True)
    studio = Studio(source, host=args.host, port=args.port)
    source.start_live()
    print(f"Replay of {args.file}: open {studio.url} (the Replay timeline scrubs, plays and sets the speed)",
          flush=True)
    _wait_for_signal()
    source.shutdown()
    studio.close()
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in ("serve", "run", "replay", "recording", "-h", "--help"):
        argv = ["serve", *argv]
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        commands = {"serve": serve, "run": run_headless, "replay": replay, "recording": repair_recording}
        return commands[args.command](args)
    except (FileNotFoundError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
