"""metrics.json, report.md and the plots (``localize.offline.report_plots``), from the run records
under ``<report>/runs``.

The report can be rebuilt at any time from the run records alone (``write_report``), so a
resumed evaluation ends with the same report as an uninterrupted one.
"""

from __future__ import annotations

import json
import logging
from collections import defaultdict
from pathlib import Path

import numpy as np

from core.atomic import atomic_write_json, atomic_write_text
from localize.filter.quality import reliability, worst_gap
from localize.offline.metrics import (
    CALIBRATION_TARGET,
    calibration,
    convergence_frame,
    error_stats,
    false_convergence,
    health_stats,
    lost_track,
    timing_stats,
)
from localize.offline.report_plots import (
    main_records,
    plot_calibration,
    plot_errors,
    plot_frame,
    plot_topdown,
    plot_xy,
    tracking_seed0,
)
from localize.resolve import settings_table

log = logging.getLogger(__name__)

TIMING_STAGES = ("acquisition", "segmentation", "preprocessing", "filter", "total")


def load_records(out_dir: Path) -> list[dict]:
    """All run records (``runs/<flight>/*.json``), sorted by path."""
    return [json.loads(p.read_text()) for p in sorted((Path(out_dir) / "runs").glob("*/*.json"))]


def summarize(records: list[dict], cfg) -> dict:
    """metrics.json content from the run records (of flights or recordings).

    Per flight (or recording) and mode: the tracking runs' error statistics over all frames
    of all seeds, the failure rate (share of frames with an error above
    ``failure_threshold_m``), the mean error of each seed, the true poses outside the free
    space (``truth_outside_free``: frames, largest distance m), and for global init the
    convergence frame of each seed and the share converged within ``converge_within_frames``.
    Records without truth (a recording without ground truth) give no errors: the filter's
    own health, the frames and the seeds only.
    """
    mc = cfg.metrics
    flights: dict = defaultdict(dict)
    groups: dict = defaultdict(list)
    for r in main_records(records):
        groups[(r["flight"], r["mode"], r["init"])].append(r)
    for (flight, mode, init), runs in sorted(groups.items()):
        entry = flights[flight].setdefault(mode, {})
        if "position_error_m" not in runs[0]:
            own = entry if init == "tracking" else entry.setdefault(init, {})
            own.update(_health(runs))
            own.update(seeds=[int(r["seed"]) for r in runs],
                       num_frames=int(runs[0]["num_frames"]),
                       dropped_frames=int(runs[0].get("dropped_frames", 0)),
                       num_particles=int(runs[0]["filter_particles"]))
            continue
        pos = np.concatenate([r["position_error_m"] for r in runs])
        yaw = np.concatenate([r["yaw_error_deg"] for r in runs])
        fail = float(np.mean(pos > mc.failure_threshold_m))
        if init == "tracking":
            entry.update(error_stats(pos, yaw))
            entry["failure_rate"] = fail
            entry["lost_rate"] = float(np.mean([
                lost_track(r["position_error_m"], r["timestamps"], mc.failure_threshold_m,
                           mc.lost_after_s) for r in runs]))
            entry["false_convergence_rate"] = _false_convergence_rate(runs, mc)
            entry.update(_health(runs))
            entry.update(_calibration(runs, pos, mc.calibration_within_m))
            entry["seeds"] = [int(r["seed"]) for r in runs]
            entry["per_seed_mean_m"] = [float(np.mean(r["position_error_m"])) for r in runs]
            entry["num_frames"] = int(runs[0]["num_frames"])
            entry["dropped_frames"] = int(runs[0].get("dropped_frames", 0))
            entry["num_particles"] = int(runs[0]["filter_particles"])
            outside = [r["truth_outside_free"] for r in runs if "truth_outside_free" in r]
            if outside:
                entry["truth_outside_free"] = {"frames": max(o["frames"] for o in outside),
                                               "max_m": max(o["max_m"] for o in outside)}
        else:
            conv = [convergence_frame(np.array(r["position_error_m"]),
                                      mc.converge_threshold_m) for r in runs]
            within = [c is not None and c <= mc.converge_within_frames for c in conv]
            after = [np.array(r["position_error_m"])[c:] for r, c in zip(runs, conv,
                                                                         strict=True)
                     if c is not None]
            entry[init] = {
                "convergence_frames": conv,
                "converged_within_frames": int(mc.converge_within_frames),
                "converged_within_rate": float(np.mean(within)),
                "threshold_m": float(mc.converge_threshold_m),
                "mean_error_after_convergence_m": (float(np.mean(np.concatenate(after)))
                                                   if after else None),
                "failure_rate": fail,
                "false_convergence_rate": _false_convergence_rate(runs, mc),
                "seeds": [int(r["seed"]) for r in runs],
                **_calibration(runs, pos, mc.calibration_within_m),
            }
    timing_by_mode = {}
    for mode in {r["mode"] for r in main_records(records)}:
        runs = [r for r in main_records(records) if r["mode"] == mode and r["init"] == "tracking"]
        runs = runs or [r for r in main_records(records) if r["mode"] == mode]  # global runs alone
        if runs:
            timing_by_mode[mode] = {s: timing_stats(np.concatenate([r["timing_ms"][s]
                                                                    for r in runs]))
                                    for s in TIMING_STAGES}
    main_mode = "cnn" if "cnn" in timing_by_mode else next(iter(sorted(timing_by_mode)), None)
    out = {
        "flights": {f: dict(sorted(m.items())) for f, m in sorted(flights.items())},
        "timing_ms": timing_by_mode.get(main_mode, {}),
        "timing_mode": main_mode,
        "timing_ms_by_mode": timing_by_mode,
        "dataset": str(cfg.dataset),
        "paper": {"mean_position_error_m": float(cfg.report.paper_error_m),
                  "total_ms": float(cfg.report.paper_time_ms),
                  "lidar_error_m": float(cfg.report.lidar_error_m)},
    }
    out["targets"] = targets(out, cfg)
    return out


def _false_convergence_rate(runs: list[dict], mc) -> float | None:
    """Share of runs that declared convergence falsely (``metrics.false_convergence``: status
    ``tracking`` while above ``failure_threshold_m`` for over ``lost_after_s``); None when the
    records carry no status."""
    if not all("status" in r for r in runs):
        return None
    return float(np.mean([false_convergence(r["position_error_m"], r["timestamps"], r["status"],
                                            mc.failure_threshold_m, mc.lost_after_s)
                          for r in runs]))


def _health(runs: list[dict]) -> dict:
    """The filter's own health over the frames of runs (``metrics.health_stats``); {} for
    records without status."""
    status = [s for r in runs for s in r.get("status", [])]
    if not status:
        return {}
    return health_stats(status, np.concatenate([r["confidence"] for r in runs]))


def _calibration(runs: list[dict], pos_err: np.ndarray, within_m: float) -> dict:
    """``{"calibration": ...}`` (``metrics.calibration``) over the frames of runs, whose
    errors ``pos_err`` are concatenated in the runs' order; {} for records without
    confidence."""
    if not all("confidence" in r for r in runs):
        return {}
    out = {"calibration": calibration(pos_err, np.concatenate([r["confidence"] for r in runs]),
                                      within_m)}
    if all("quality" in r for r in runs):
        q = np.concatenate([np.asarray(r["quality"], dtype=np.float64) for r in runs])
        if np.isfinite(q).any():
            out["quality"] = reliability(q, pos_err < within_m)
    return out


def model_of(out_dir: Path, cfg, modes) -> dict:
    """The model a report's cnn runs used: the segnet.onnx path and its digest (the report
    folder's config.json ``onnx_sha256``); None where no cnn run is in the report."""
    if "cnn" not in modes:
        return {"onnx_model": None, "onnx_sha256": None}
    from localize.frontend.segmenter import runtime_model

    path = Path(out_dir) / "config.json"
    conf = json.loads(path.read_text()) if path.is_file() else {}
    onnx = runtime_model(str(cfg.onnx_model), str(cfg.dataset), bool(cfg.segnet_int8))
    return {"onnx_model": str(onnx),
            "onnx_sha256": conf.get("onnx_sha256")}


def targets(m: dict, cfg) -> list[dict]:
    """The issue's targets, each with the measured value and whether it is met."""
    out = []
    fl = m["flights"]

    def add(name, value, ok, goal):
        out.append({"target": name, "goal": goal, "value": value,
                    "met": None if ok is None else bool(ok)})

    paper = fl.get("paper", {})
    if "cnn" in paper and "mean_position_error_m" in paper["cnn"]:
        v = paper["cnn"]["mean_position_error_m"]
        add("paper flight, cnn, tracking: mean position error", v, v <= 0.10, "<= 0.10 m")
    clut = fl.get("cluttered", {})
    if all(k in clut and "mean_position_error_m" in clut[k] for k in ("cnn", "none")):
        ratio = clut["none"]["mean_position_error_m"] / max(
            clut["cnn"]["mean_position_error_m"], 1e-9)
        add("cluttered flight: none / cnn mean error", ratio, ratio >= 2.0, ">= 2")
    if all(k in clut and "mean_position_error_m" in clut[k] for k in ("cnn", "oracle")):
        ratio = clut["cnn"]["mean_position_error_m"] / max(
            clut["oracle"]["mean_position_error_m"], 1e-9)
        add("cluttered flight: cnn / oracle mean error", ratio, ratio <= 1.25, "<= 1.25")
    for mode in ("cnn", "oracle", "none"):
        g = paper.get(mode, {}).get("global")
        if g and "converged_within_rate" in g:
            add(f"paper flight, {mode}, global init: converged within "
                f"{g['converged_within_frames']} frames", g["converged_within_rate"],
                g["converged_within_rate"] >= 0.9, ">= 90% of seeds")
    tm = m.get("timing_ms", {})
    if tm:
        f = tm["filter"]["avg"]
        add(f"filter update ({m['timing_mode']} mode, {cfg.filter.num_particles} particles), "
            "avg per frame", f, f <= 20.0, "<= 20 ms")
        seg_filter = tm["segmentation"]["avg"] + tm["preprocessing"]["avg"] + f
        add(f"segmentation + edges + filter ({m['timing_mode']}), avg per frame", seg_filter,
            seg_filter <= 50.0, "<= 50 ms")
    return out


# --- plots ---------------------------------------------------------------------------------


def versus_paper(error_m: float, paper_m: float) -> str:
    """``"3.5x better"`` when ``error_m`` is 3.5 times smaller than the paper's ``paper_m``,
    ``"3.5x worse"`` when 3.5 times larger (both mean errors in metres)."""
    ratio = paper_m / max(error_m, 1e-9)
    return f"{ratio:.1f}x better" if ratio >= 1.0 else f"{1.0 / ratio:.1f}x worse"


def _fmt(v, digits: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


#: What each flight set is for, as the report says it.
FLIGHT_SET_NOTE = {
    "test": "test flights (datagen's render_flights): no setting was chosen on them; settings "
            "are tuned on the validation flights (flight_set=val)",
    "val": "validation flights (datagen's val_flights, <name>_val): the flights settings are "
           "tuned on; report figures from the test flights (flight_set=test)",
}


def _header(m: dict, cfg) -> list[str]:
    """Title, the flights used, the filter's settings and the paper's figures."""
    f = cfg.filter
    flight_set = m.get("flight_set", "test")
    return [
        f"# Localization report: {cfg.name}",
        "",
        f"Flights: {', '.join(m.get('flights_used', []))}, the "
        f"{FLIGHT_SET_NOTE.get(flight_set, flight_set)}. Flights made with "
        f"realism={m.get('realism', 'ideal')}.",
        "",
        f"Dataset `{m['dataset']}`. Filter: {f.num_particles} particles, likelihood "
        f"k = {f.likelihood.k}, sigma = {f.likelihood.sigma} "
        f"of a {f.likelihood.search_px}-pixel search reach"
        + (f", k scaled down in frames of fewer than {f.likelihood.lines_ref} lines"
           if f.likelihood.lines_ref else "")
        + "".join(f"; mode {mode}: " + ", ".join(f"{k} = {v}" for k, v in over.items())
                  for mode, over in f.mode_likelihood.items())
        + f". Motion noise per frame (horizontal m, vertical m, yaw deg): "
        f"{list(f.motion_std)}"
        + "".join(f"; mode {mode}: {list(std)}"
                  for mode, std in f.mode_motion_std.items())
        + f". Seeds: {list(cfg.seeds)}.",
        f"Paper (Buyval et al. 2017): mean error {cfg.report.paper_error_m} m, "
        f"{cfg.report.paper_time_ms:g} ms per frame on a GTX 1050; a LIDAR method "
        f"~{cfg.report.lidar_error_m} m.",
        "",
        *_settings(m),
    ]


def _settings(m: dict) -> list[str]:
    """The settings that differ from their defaults and the layer that set each
    (``localize.resolve``)."""
    rows = m.get("settings", [])
    if not rows:
        return []
    return ["Settings that differ from the defaults (localize/config.py):", "",
            "| setting | value | default | set by |", "|---|---|---|---|",
            *(f"| {r['key']} | `{r['value']}` | `{r['default']}` | {r['set_by']} |"
              for r in rows), ""]


def _accuracy(m: dict, cfg) -> list[str]:
    """Tracking errors per flight and mode, against the paper."""
    paper_err = cfg.report.paper_error_m
    lines = ["## Accuracy, tracking init", "",
             "| flight | mode | mean (m) | median (m) | RMSE (m) | p95 (m) | yaw (deg) | failures "
             f"| lost | coasting | confidence | vs paper {paper_err} m |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for flight, modes in m["flights"].items():
        for mode, s in modes.items():
            if "mean_position_error_m" not in s:
                continue
            lines.append(
                f"| {flight} | {mode} | {_fmt(s['mean_position_error_m'])} | "
                f"{_fmt(s['median_m'])} | {_fmt(s['rmse_m'])} | {_fmt(s['p95_m'])} | "
                f"{_fmt(s['mean_yaw_error_deg'], 2)} | {_fmt(100 * s['failure_rate'], 1)}% | "
                f"{_fmt(100 * s['lost_rate'], 0)}% | "
                f"{_fmt(100 * s['coasting_rate'], 1) + '%' if 'coasting_rate' in s else '-'} | "
                f"{_fmt(s['mean_confidence'], 2) if 'mean_confidence' in s else '-'} | "
                f"{versus_paper(s['mean_position_error_m'], paper_err)} |")
    mc = cfg.metrics
    outside = [f"{flight} {s['truth_outside_free']['frames']} of {s['num_frames']} (up to "
               f"{s['truth_outside_free']['max_m']:.2f} m)"
               for flight, modes in m["flights"].items() for s in modes.values()
               if s.get("truth_outside_free", {}).get("frames")]
    if outside:
        lines += ["", "True poses outside the free space (the filter penalises them beyond "
                  "filter.free_space_slack; the map: datagen's world.z_range, "
                  "world.camera_margin, world.free_close, world.free_max_hole, "
                  "world.obstacle_span): "
                  + "; ".join(dict.fromkeys(outside)) + "."]
    return lines + ["", f"Failures: frames with an error above {mc.failure_threshold_m} m. "
                    f"Lost: runs whose error stayed above {mc.failure_threshold_m} m for more "
                    f"than {mc.lost_after_s:g} s. Coasting: frames that did not weigh the "
                    "particles (nothing usable in the image, or no particle fit it). "
                    "Confidence: the filter's own, per frame, averaged (0 to 1).", ""]


def calibrations(modes: dict) -> dict[str, dict[str, dict]]:
    """A flight's calibrations (metrics.json ``calibration``) by init and mode, from its
    metrics.json entry (mode -> statistics)."""
    out: dict[str, dict[str, dict]] = {}
    for mode, s in modes.items():
        for init, own in (("tracking", s), ("global", s.get("global", {}))):
            if "calibration" in own:
                out.setdefault(init, {})[mode] = own["calibration"]
    return out


def _calibration_table(m: dict) -> list[str]:
    """The filter's confidence against its error, per flight, init and mode."""
    rows = [(fl, init, mode, c) for fl, modes in m["flights"].items()
            for init, by_mode in calibrations(modes).items() for mode, c in by_mode.items()]
    if not rows:
        return []
    cal = rows[0][3]
    hi, within = cal["high_confidence"]["min_confidence"], cal["within_m"]
    bins = [f"[{lo:g}, {up:g}{']' if i == len(cal['bins']) - 1 else ')'}"
            for i, (lo, up) in enumerate(b["confidence"] for b in cal["bins"])]
    lines = ["## Confidence calibration", "",
             f"Target: when the filter's confidence is >= {hi:g}, the error is below "
             f"{within:g} m in >= {100 * CALIBRATION_TARGET:.0f}% of those frames. Per "
             f"confidence bin: the share of its frames within {within:g} m (the bin's share "
             "of all frames).", "",
             f"| flight | init | mode | frames >= {hi:g} | of those within {within:g} m | met | "
             + " | ".join(bins) + " |", "|---|---|---|---|---|---|" + "---|" * len(bins)]

    def pct(v):
        return "-" if v is None else f"{100 * v:.1f}%"

    for fl, init, mode, c in rows:
        h = c["high_confidence"]
        met = "-" if h["within_share"] is None else (
            "yes" if h["within_share"] >= CALIBRATION_TARGET else "**no**")
        lines.append(f"| {fl} | {init} | {mode} | {pct(h['frame_share'])} | "
                     f"{pct(h['within_share'])} | {met} | "
                     + " | ".join(f"{pct(b['within_share'])} ({pct(b['frame_share'])})"
                                  for b in c["bins"]) + " |")
    return [*lines, ""]


def _quality_table(m: dict) -> list[str]:
    """The calibrated quality's reliability per flight, init and mode: per decile of
    predicted quality, the share of its frames within the bound (the decile's mean
    quality, its frames)."""
    rows = [(fl, init, mode, own["quality"]) for fl, modes in m["flights"].items()
            for mode, s in modes.items()
            for init, own in (("tracking", s), ("global", s.get("global", {})))
            if "quality" in own]
    if not rows:
        return []
    lines = ["## Quality reliability", "",
             "Per decile of the estimates' `quality` (the calibrated probability of being "
             "within 0.3 m): the share of its frames within 0.3 m, the decile's mean quality "
             "and its frames. Calibrated: each decile's share within 0.1 of its mean quality.",
             "", "| flight | init | mode | worst gap | "
             + " | ".join(f"[{b['lo']:.1f}, {b['hi']:.1f})" for b in rows[0][3]) + " |",
             "|---|---|---|---|" + "---|" * len(rows[0][3])]
    for fl, init, mode, table in rows:
        gap = worst_gap(table)
        lines.append(f"| {fl} | {init} | {mode} | {'-' if gap is None else f'{gap:.2f}'} | "
                     + " | ".join("-" if not b["frames"] else
                                  f"{b['observed']:.2f} / {b['predicted']:.2f} ({b['frames']})"
                                  for b in table) + " |")
    return [*lines, ""]


def _global(m: dict, cfg) -> list[str]:
    """Convergence from a uniform start, where global runs exist."""
    glob = [(fl, mode, s["global"]) for fl, modes in m["flights"].items()
            for mode, s in modes.items() if "converged_within_rate" in s.get("global", {})]
    if not glob:
        return []
    n = cfg.metrics.converge_within_frames
    lines = ["## Global localization (uniform start)", "",
             f"Converged: error below {cfg.metrics.converge_threshold_m} m from that frame "
             "to the end of the flight.", "",
             f"False convergence: status `tracking` while more than "
             f"{cfg.metrics.failure_threshold_m} m off for over {cfg.metrics.lost_after_s} s.",
             "",
             f"| flight | mode | converged within {n} frames | convergence frame per seed "
             "| mean error after convergence (m) | false convergence |",
             "|---|---|---|---|---|---|"]
    for fl, mode, g in glob:
        fc = g.get("false_convergence_rate")
        lines.append(f"| {fl} | {mode} | {100 * g['converged_within_rate']:.0f}% | "
                     f"{', '.join(_fmt(c) for c in g['convergence_frames'])} | "
                     f"{_fmt(g['mean_error_after_convergence_m'])} | "
                     f"{'-' if fc is None else f'{100 * fc:.0f}%'} |")
    return [*lines, ""]


def _timing(m: dict, cfg) -> list[str]:
    """Time per frame and stage, as the paper's Table 1."""
    tbm = m.get("timing_ms_by_mode", {})
    if not tbm:
        return []
    modes = sorted(tbm)
    lines = ["## Time per frame (ms, min / avg / max), as the paper's Table 1", "",
             "| stage | " + " | ".join(modes) + " | paper (GPU) |",
             "|---|" + "---|" * (len(modes) + 1)]
    paper_col = {"segmentation": "167", "total": f"{cfg.report.paper_time_ms:g}"}
    for stage in TIMING_STAGES:
        cells = [f"{tbm[mo][stage]['min']:.1f} / {tbm[mo][stage]['avg']:.1f} / "
                 f"{tbm[mo][stage]['max']:.1f}" for mo in modes]
        lines.append(f"| {stage} | " + " | ".join(cells) + f" | {paper_col.get(stage, '-')} |")
    return lines + ["", "Acquisition: reading the frame (PNG) from disk; segmentation: SegNet "
                    "through onnxruntime (cnn only); preprocessing: edge map and distance "
                    "transforms; filter: motion, likelihood, resampling for one filter. Measured "
                    "on a 2-core CPU shared with other jobs, so these may be pessimistic; "
                    "`benchmarks/localize_speed.py` measures the stages alone.", ""]


def _targets_and_plots(m: dict, plots: dict[str, list[str]]) -> list[str]:
    """The targets table, the plots per flight and where the trajectories are."""
    lines = []
    if m.get("targets"):
        lines += ["## Targets", "", "| target | goal | measured | met |", "|---|---|---|---|"]
        for t in m["targets"]:
            met = {True: "yes", False: "**no**", None: "-"}[t["met"]]
            lines.append(f"| {t['target']} | {t['goal']} | {_fmt(t['value'])} | {met} |")
        lines.append("")
    lines += ["## Plots", ""]
    for flight, files in plots.items():
        lines += [f"### {flight}", ""]
        for fpath in files:
            lines += [f"![{Path(fpath).stem}]({fpath})", ""]
    return lines + ["Trajectories (TUM, world_from_body): `trajectories/<flight>/<mode>_seed<k>"
                    ".txt` (tracking) and `<mode>_global_seed<k>.txt`; per-frame records: "
                    "`runs/`.", ""]


def results_sections(m: dict, cfg) -> list[str]:
    """The sections of a flight's or a recording's report: accuracy, confidence calibration,
    the quality's reliability and global convergence (where there is truth), time per frame."""
    truth = any("mean_position_error_m" in s for modes in m["flights"].values()
                for s in modes.values())
    return [*(_accuracy(m, cfg) if truth else []), *_calibration_table(m), *_quality_table(m),
            *_global(m, cfg), *_timing(m, cfg)]


def render_markdown(m: dict, cfg, plots: dict[str, list[str]]) -> str:
    """report.md text."""
    return "\n".join([*_header(m, cfg), *results_sections(m, cfg),
                      *_targets_and_plots(m, plots)])


def write_report(ctx) -> Path:
    """Write metrics.json, the plots and report.md under the report folder.

    Returns:
        Path of report.md.
    """
    out = ctx.out_dir
    flight_set = str(ctx.cfg.flight_set)
    in_set = set(ctx.dataset.flight_names(flight_set))
    records = [r for r in load_records(out) if r["flight"] in in_set]
    if not records:
        raise RuntimeError(f"no run records of {flight_set} flights under {out / 'runs'}; "
                           "nothing to report")
    metrics = {**summarize(records, ctx.cfg),
               "model": model_of(out, ctx.cfg, {r["mode"] for r in main_records(records)}),
               "realism": ctx.dataset.realism,
               "flight_set": flight_set, "flight_set_note": FLIGHT_SET_NOTE[flight_set],
               "flights_used": sorted({r["flight"] for r in records}),
               "settings": settings_table(ctx.cfg)}
    atomic_write_json(out / "metrics.json", metrics)
    plots: dict[str, list[str]] = {}
    for flight in sorted({r["flight"] for r in main_records(records)}):
        files = []
        if tracking_seed0(records, flight):
            plot_xy(records, flight, out / "plots" / f"{flight}_xy.png")
            plot_topdown(records, flight, ctx.world, out / "plots" / f"{flight}_topdown.png")
            try:
                plot_frame(ctx, records, flight, out / "plots" / f"{flight}_frame.png")
                files.append(f"plots/{flight}_frame.png")
            except (FileNotFoundError, ValueError) as err:  # a missing frame must not stop it
                log.warning("frame figure for %s skipped: %s", flight, err)
            files = [f"plots/{flight}_xy.png", f"plots/{flight}_topdown.png"] + files
        plot_errors(records, flight, out / "plots" / f"{flight}_error.png",
                    float(ctx.cfg.metrics.converge_threshold_m))
        files.append(f"plots/{flight}_error.png")
        cal = calibrations(metrics["flights"][flight])
        if cal:
            plot_calibration(cal, flight, out / "plots" / f"{flight}_calibration.png")
            files.append(f"plots/{flight}_calibration.png")
        plots[flight] = files
    report = out / "report.md"
    atomic_write_text(report, render_markdown(metrics, ctx.cfg, plots))
    return report
