"""E2: CBF vs EDF collision constraints, on ground-truth and perceived maps, and a gamma sweep.

    python -m bench.experiments.e2_cbf_vs_edf [--quick] [--workers N] [--ray ADDRESS] [--maps M ...] [--no-sweep]

The paper's protocol: 15 seeded random scenes (8 boxes of 0.6 m, one or two layers, in 5 × 5 m;
`core.scene.random_scene`) × 3 reference speeds = 45 trials, each with the CBF constraint
(dh/dt ≥ −gamma h, gamma 1) and the EDF baseline (h ≥ 0), both with delta 0.25 m, on the ground-truth
map (the simulator's exact EDF, exact odometry), on the perceived object-level map (POCD from the two
depth cameras through the sensor model: depth noise 0.005 z², 2 % dropouts, flying pixels, odometry
drift 0.01 m/√m and 0.01 rad/√rad, frames stamped 20 ms late; `core.params.SensorParams`), on the same
with the EDF of the paper's 9a (distance to the observed surfaces only, `MappingParams.edf_geometry`
'surface', instead of boxes completed where unseen), and on the perceived map with the paper's
closed-loop delay (0.45 s perception, 0.05 s actuation, as E3). `--maps` runs some of them. The robot
drives from (−3.5, 0) to (3.5, 0) with whole-body navigation [base, EE]; the reference advances along
the A* path at the trial's speed (`SequencerParams.nominal_speed_mps`). A* grows the boxes by the base's
footprint only (its circumscribed radius, 0.62 m), so the clearance beyond the body is what the constraint
makes of it; grown by the whole clearance (0.8 m, the studio's default), planned paths keep h ≈ 0 and
the two constraints have little to differ on.
Gamma sweep: the CBF with several gammas on the perceived map at the highest speed, same scenes
(`--no-sweep` leaves it out).

Measured per trial: reached the goal (within 60 s), collision-free (no MuJoCo contact of any robot
geom with a box), minimum clearance (true robot geometry to the nearest box), time to goal, driven
path length, and the approach speed as the paper's Fig. 7b: the velocity of the robot's closest point
projected on −∇EDF, i.e. how fast the true clearance shrinks, over the control periods with the clearance
under 0.6 m (its mean with receding counted as zero, and its 90th percentile). The total base speed near
obstacles says little: driving past a box at speed does not approach it.
"""

from __future__ import annotations

import argparse
import logging
import math
from dataclasses import asdict, replace
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from app.runtime import Runtime
from bench.experiments.measures import NEAR_OBSTACLE_M, run_metrics, solver_figures
from bench.experiments.report_files import (
    finish_experiment,
    md_table,
    rate,
    save_figure,
    stat,
    write_markdown,
)
from bench.experiments.trials import Trial, experiment_args, quiet_logs, runtime_config, trial_results, tunables
from core.params import MappingParams
from core.scene import random_scene
from tasks import BasePose, BaseSubtask, TaskSequence

log = logging.getLogger(__name__)

NAME = "e2_cbf_vs_edf"
SPEEDS_MPS = (0.4, 0.7, 1.0)
CONSTRAINTS = ("cbf", "edf")
MAPS = ("ground_truth", "object", "object_surface", "object_delayed")
"""Map conditions: the simulator's exact EDF; the perceived object map (sensor model on); the same with the
paper's surface EDF (9a); the perceived map with the paper's closed-loop delay (`DELAYS_S`)."""
MAP_KIND = {"ground_truth": "ground_truth", "object": "object", "object_surface": "object", "object_delayed": "object"}
MAPPING = {"object_surface": replace(MappingParams(), edf_geometry="surface")}
"""Mapping parameters of a condition (default `MappingParams()`: boxes completed where unseen)."""
DELAYS_S = {"object_delayed": (0.45, 0.05)}
"""(perception, actuation) delay (s): camera 0.13 + mapping 0.35 on the paper's robot, solve rounded up."""
LABEL = {"ground_truth": "GT", "object": "perceived", "object_surface": "perceived, 9a", "object_delayed":
         "perceived+0.5 s"}
GAMMAS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)
SCENES = 15
TIMEOUT_S = 60.0
PAPER = ("15 random scenes × 3 speeds = 45 trials, ground-truth and perceived maps, same delta: the CBF keeps "
         "more clearance, approaches obstacles slower and has a higher collision-free rate with perceived maps; "
         "as gamma grows the CBF tends to the EDF constraint (no numbers in our summary of the paper)")


def trial(params: dict) -> dict:
    """One navigation run through a random scene with one map, constraint, speed and gamma."""
    scene = random_scene(params["seed"])
    seq = TaskSequence(name="cross the boxes", subtasks=[
        BaseSubtask(name="to the goal", target=BasePose(x=scene.goal[0], y=scene.goal[1], yaw_deg=0.0),
                    timeout_s=TIMEOUT_S)])
    perception_s, actuation_s = DELAYS_S.get(params["map"], (0.0, 0.0))
    cfg = runtime_config(map_kind=MAP_KIND[params["map"]], seed=params["seed"],
                         perception_delay_s=perception_s, actuation_delay_s=actuation_s,
                         mapping=MAPPING.get(params["map"], tunables().mapping),
                         htmpc=replace(tunables().htmpc, constraint=params["constraint"],
                                       gamma=params["gamma"]),
                         sequencer=replace(tunables().sequencer, nominal_speed_mps=params["speed"],
                                           inflation_m=tunables().robot.footprint_radius_m))
    rt = Runtime(cfg, scene=scene, sequence=seq)
    run_log = rt.run_lockstep(TIMEOUT_S + 2.0)
    metrics = run_metrics(rt.run_state, run_log, rt.world.collisions, rt.controller.counts)
    metrics["time_to_goal_s"] = metrics["duration_s"] if metrics["finished"] else math.nan
    return {**metrics, "status": rt.status_line()}


def main_trials(seeds: list[int], speeds: tuple[float, ...], maps: tuple[str, ...]) -> list[Trial]:
    """The 2 × 2 × seeds × speeds grid (gamma 1, the paper's default)."""
    return [Trial(trial, {"part": "main", "seed": s, "speed": v, "map": m, "constraint": c, "gamma": 1.0})
            for m in maps for c in CONSTRAINTS for v in speeds for s in seeds]


def gamma_trials(seeds: list[int], gammas: tuple[float, ...], speed: float) -> list[Trial]:
    """The CBF on the perceived map with each gamma (gamma 1 and the EDF come from the main grid)."""
    return [Trial(trial, {"part": "gamma", "seed": s, "speed": speed, "map": "object", "constraint": "cbf",
                          "gamma": g}) for g in gammas if g != 1.0 for s in seeds]


def _group(results: list[dict], **match) -> list[dict]:
    return [r for r in results if all(r.get(k) == v for k, v in match.items())]


FIGURE_KEYS = {"success": ("finished", "rate"), "collision_free": ("collision_free", "rate"),
               "min_clearance_m_median": ("min_clearance_m", "median"),
               "min_clearance_m_min": ("min_clearance_m", "min"),
               "time_s_median": ("time_to_goal_s", "median"), "path_m_median": ("path_length_m", "median"),
               "approach_speed_mps_median": ("approach_speed_mps", "median"),
               "approach_speed_p90_mps_median": ("approach_speed_p90_mps", "median"),
               "speed_near_obstacles_mps_median": ("speed_near_obstacles_mps", "median")}


def _figures_of(rows: list[dict], prefix: str) -> dict[str, float]:
    out = {f"{prefix}_trials": float(len(rows))}
    for name, (key, how) in FIGURE_KEYS.items():
        out[f"{prefix}_{name}"] = rate(rows, key) if how == "rate" else stat(rows, key, how)
    return out


def summarise(results: list[dict], speeds: tuple[float, ...], gamma_speed: float) -> dict[str, float]:
    """Per map × constraint (all speeds) and per speed; per gamma at the sweep's speed."""
    figures: dict[str, float] = {}
    main = _group(results, part="main")
    for m in MAPS:
        for c in CONSTRAINTS:
            rows = _group(main, map=m, constraint=c)
            if rows:
                figures |= _figures_of(rows, f"{m}_{c}")
            for v in speeds:
                sub = _group(rows, speed=v)
                if sub:
                    figures |= _figures_of(sub, f"{m}_{c}_{v:g}mps")
    sweep = _group(results, map="object", speed=gamma_speed)
    for g in sorted({r["gamma"] for r in sweep if r["constraint"] == "cbf"}):
        figures |= _figures_of(_group(sweep, constraint="cbf", gamma=g), f"gamma_{g:g}")
    if _group(sweep, constraint="edf"):
        figures |= _figures_of(_group(sweep, constraint="edf"), "gamma_inf_edf")
    return figures | solver_figures(results)


def _maps_run(results: list[dict]) -> list[str]:
    """The map conditions of the main grid that were run (all, or those of `--maps`)."""
    return [m for m in MAPS if _group(results, part="main", map=m)]


def _bar(ax, results: list[dict], key: str, how: str, speeds: tuple[float, ...], ylabel: str) -> None:
    colours = {"cbf": "tab:blue", "edf": "tab:orange"}
    maps = _maps_run(results)
    labels = [f"{LABEL[m]}\n{v:g} m/s" for m in maps for v in speeds]
    x = np.arange(len(labels))
    for j, c in enumerate(CONSTRAINTS):
        vals = []
        for m in maps:
            for v in speeds:
                rows = _group(results, part="main", map=m, constraint=c, speed=v)
                vals.append(rate(rows, key) if how == "rate" else stat(rows, key, how))
        ax.bar(x + (j - 0.5) * 0.38, vals, 0.38, color=colours[c], label=c.upper())
    ax.set_xticks(x, labels, fontsize=8)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)


def figures_png(results: list[dict], speeds: tuple[float, ...], gamma_speed: float, out_dir: Path) -> list[str]:
    """Bars per map × speed × constraint; clearance distributions; the gamma sweep."""
    names = []
    fig, axes = plt.subplots(2, 2, figsize=(12, 8))
    _bar(axes[0, 0], results, "collision_free", "rate", speeds, "collision-free rate")
    _bar(axes[0, 1], results, "finished", "rate", speeds, "success rate (goal in 60 s)")
    _bar(axes[1, 0], results, "min_clearance_m", "median", speeds, "min clearance (m, median)")
    _bar(axes[1, 1], results, "approach_speed_p90_mps", "median",
         speeds, f"approach speed p90, clearance < {NEAR_OBSTACLE_M} m (m/s)")
    fig.suptitle("E2: CBF vs EDF (delta 0.25 m, gamma 1)")
    names.append(save_figure(fig, out_dir, "cbf_vs_edf"))

    fig, ax = plt.subplots(figsize=(10, 4.5))
    data, labels = [], []
    for m in _maps_run(results):
        for c in CONSTRAINTS:
            rows = _group(results, part="main", map=m, constraint=c)
            vals = [r["min_clearance_m"] for r in rows if "error" not in r and r.get("min_clearance_m") is not None]
            data.append(vals or [np.nan])
            labels.append(f"{LABEL[m]}\n{c.upper()}")
    ax.boxplot(data, tick_labels=labels)
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_ylabel("minimum clearance per trial (m)")
    ax.set_title("E2: minimum clearance over all trials (true geometry)")
    names.append(save_figure(fig, out_dir, "clearance_distribution"))

    sweep = _group(results, map="object", speed=gamma_speed)
    gammas = sorted({r["gamma"] for r in sweep if r["constraint"] == "cbf"})
    if len(gammas) > 1:
        fig, axes = plt.subplots(1, 3, figsize=(13, 4))
        edf = _group(sweep, constraint="edf")
        for ax, key, how, label in ((axes[0], "min_clearance_m", "median", "min clearance (m, median)"),
                                    (axes[1], "time_to_goal_s", "median", "time to goal (s, median)"),
                                    (axes[2], "collision_free", "rate", "collision-free rate")):
            vals = [rate(_group(sweep, constraint="cbf", gamma=g), key) if how == "rate"
                    else stat(_group(sweep, constraint="cbf", gamma=g), key, how) for g in gammas]
            ax.semilogx(gammas, vals, "o-", label="CBF")
            if edf:
                ax.axhline(rate(edf, key) if how == "rate" else stat(edf, key, how), color="tab:orange", ls="--",
                           label="EDF (gamma → ∞)")
            ax.set_xlabel("gamma")
            ax.set_ylabel(label)
            ax.legend(fontsize=8)
        fig.suptitle(f"E2: gamma sweep, perceived map, {gamma_speed:g} m/s")
        names.append(save_figure(fig, out_dir, "gamma_sweep"))
    return names


def _row(figures: dict[str, float], prefix: str, label: list) -> list:
    return label + [int(figures.get(f"{prefix}_trials", 0))] + [figures.get(f"{prefix}_{k}", math.nan) for k in
                    ("success", "collision_free", "min_clearance_m_median", "min_clearance_m_min",
                     "approach_speed_mps_median", "approach_speed_p90_mps_median", "speed_near_obstacles_mps_median",
                     "time_s_median", "path_m_median")]


HEADERS = ["trials", "reached goal", "collision-free", "min clearance (m, median)", "min clearance (m, worst)",
           "approach speed (m/s, mean)", "approach speed (m/s, p90)", "base speed near obstacles (m/s)",
           "time to goal (s, median)", "path (m, median)"]


def report(results: list[dict], figures: dict[str, float], speeds: tuple[float, ...], gamma_speed: float,
           pngs: list[str], out_dir: Path, quick: bool, options: str = "") -> None:
    """Markdown: the paper's claims, our tables (overall, per speed, gamma sweep), figures, failures."""
    overall = md_table(["map", "constraint", *HEADERS],
                       [_row(figures, f"{m}_{c}", [m, c.upper()]) for m in MAPS for c in CONSTRAINTS
                        if f"{m}_{c}_trials" in figures])
    per_speed = md_table(["map", "constraint", "speed (m/s)", *HEADERS],
                         [_row(figures, f"{m}_{c}_{v:g}mps", [m, c.upper(), v]) for m in MAPS for c in CONSTRAINTS
                          for v in speeds if f"{m}_{c}_{v:g}mps_trials" in figures])
    gammas = sorted(float(k.split("_")[1]) for k in figures if k.startswith("gamma_") and k.endswith("_trials")
                    and not k.startswith("gamma_inf"))
    sweep = md_table(["gamma", *HEADERS], [_row(figures, f"gamma_{g:g}", [g]) for g in gammas]
                     + ([_row(figures, "gamma_inf_edf", ["EDF (∞)"])] if "gamma_inf_edf_trials" in figures else []))
    bad = [r for r in results if "error" in r or not r.get("finished") or not r.get("collision_free")]
    failures = md_table(["part", "seed", "speed", "map", "constraint", "gamma", "reached", "contacts",
                         "max depth (m)", "min clearance (m)", "status"],
                        [[r["part"], r["seed"], r["speed"], r["map"], r["constraint"], r["gamma"], r.get("finished"),
                          r.get("collision_events"), r.get("max_penetration_m"), r.get("min_clearance_m"),
                          r.get("error") or r.get("status")] for r in bad]) if bad else "None."
    sections = [
        ("Setup", __doc__.split("\n\n", 2)[2]),
        ("Ours beside the paper", f"Paper: {PAPER}.\n\nOurs, all speeds together:\n\n{overall}"),
        ("Per speed", per_speed),
        (f"Gamma sweep (CBF, perceived map, {gamma_speed:g} m/s)", sweep),
        ("Figures", "\n\n".join(f"![{p}]({p})" for p in pngs)),
        ("Trials that failed or touched a box", failures),
    ]
    write_markdown(out_dir, NAME, "E2 — CBF vs EDF constraints", sections, quick, options)


def _options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--maps", nargs="+", choices=MAPS, default=list(MAPS), help="map conditions to run")
    parser.add_argument("--no-sweep", action="store_true", help="leave the gamma sweep out")


def main(argv: list[str] | None = None) -> dict[str, float]:
    quiet_logs()
    args = experiment_args(NAME, __doc__.splitlines()[0], argv, extra=_options)
    seeds = list(range(1 if args.quick else SCENES))
    speeds = (1.0,) if args.quick else SPEEDS_MPS
    gammas = () if args.no_sweep else (0.5, 4.0) if args.quick else GAMMAS
    gamma_speed = max(speeds)
    maps = tuple(m for m in MAPS if m in args.maps)
    trials = main_trials(seeds, speeds, maps) + gamma_trials(seeds, gammas, gamma_speed)
    results = trial_results(args, NAME, trials, "E2 scenes × speeds × maps × constraints")
    figures = summarise(results, speeds, gamma_speed)
    settings = {"seeds": seeds, "speeds_mps": list(speeds), "maps": list(maps), "constraints": list(CONSTRAINTS),
                "gammas": list(gammas), "gamma_sweep_speed_mps": gamma_speed,
                "delta_safe_m": tunables().htmpc.delta_safe_m, "timeout_s": TIMEOUT_S, "paper": PAPER,
                "sensor_model": asdict(tunables().sim.sensor)}
    options = " ".join(([f"--maps {' '.join(maps)}"] if maps != MAPS else [])
                       + (["--no-sweep"] if args.no_sweep else []))
    return finish_experiment(args, NAME, results, figures, settings,
                             lambda out: figures_png(results, speeds, gamma_speed, out),
                             lambda pngs: report(results, figures, speeds, gamma_speed, pngs, args.out, args.quick,
                                                 options),
                             show=lambda key: "mps_" not in key)


if __name__ == "__main__":
    main()
