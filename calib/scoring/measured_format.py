"""The measured-data harness's result as text for the terminal and as Markdown tables (for
:mod:`calib.scoring.measured`); both read a :class:`~calib.scoring.measured_result.MeasuredValidation` only."""

from __future__ import annotations

import math
from typing import Any

from gyrosim.units import RAD2DEG

from calib.scoring.measured_result import FIGURES, VARIANT_LABELS, VARIANTS, MeasuredValidation, RecordingResult

__all__ = ["text_block", "text_medians", "markdown", "MEDIAN_COLUMNS"]

# attribution of the recordings whose results are published (their licences ask for it)
SOURCES = {
    "broad": "BROAD — Laidig, Caruso, Cereatti, Seel, Data 6(7):72, 2021 (CC BY 4.0)",
    "imu_tk_xsens": "imu_tk's Xsens session — Tedaldi, Pretto, Menegatti, ICRA 2014 (BSD)",
    "imucal_ferraris": "imucal's Ferraris example session — mad-lab-fau/imucal (MIT)",
    "xio_fusion": "x-io Fusion's example recording — xioTechnologies/Fusion (MIT)",
    "xio_ximu_thermometer": "x-IMU export with a thermometer — scikit-kinematics test data (BSD-3-Clause)",
}
PEERS = ("imu_tk", "imucal")
MAG_KEY = "vqf_9d_mag.heading_rmse_deg"
MAG_VARIANTS = ("raw", "mag_calibrated", "full_mag_calibrated")
MEDIAN_COLUMNS = (("bias_only_vs_raw_pct", "bias only vs raw (%)"), ("full_vs_raw_pct", "full vs raw (%)"),
                  ("full_vs_bias_only_pct", "full vs bias only (%)"))
SHORT = 110  # characters of a command's message shown in the text block (the JSON keeps it whole)


def _num(x: float, prec: int) -> str:
    return "—" if x is None or not math.isfinite(x) else f"{x:.{prec}f}"


def _pct(x: float | None) -> str:
    if x is None or not math.isfinite(x):
        return "—"
    return "0.0" if abs(x) < 0.05 else f"{x:+.1f}"


def _prec(key: str) -> int:
    return 4 if key.endswith("_m_s2") else 2


def _columns(rec: RecordingResult) -> list[str]:
    present = {v for k, vs in rec.figures.items() if k != MAG_KEY for v in vs}
    return [v for v in (*VARIANTS, *PEERS) if v in present]


def _vec(values: Any, scale: float = 1.0, prec: int = 4) -> str:
    if not values:
        return "—"
    return " ".join("—" if v is None else f"{v * scale:+.{prec}f}" for v in values)


def _pm(values: Any, stds: Any, prec: int = 4) -> str:
    if not values:
        return "—"
    stds = stds or [None] * len(values)
    return "  ".join(f"{v:+.{prec}f}" + ("" if s is None else f"±{s:.{prec}f}") for v, s in zip(values, stds))


def _run_line(run) -> str:
    tail = f", status {run.status}" if run.status else ""
    msg = run.message if len(run.message) <= SHORT else run.message[:SHORT - 1] + "…"
    return f"  {run.text} → exit {run.exit_code}{tail}" + (f": {msg}" if msg and not run.status else "")


def _calibration_lines(cal: dict) -> list[str]:
    if not cal:
        return ["  applied: nothing (no calibration was written)"]
    def g(key: str):   # what calib apply uses (the estimate in a file written before the applied block)
        return cal.get(f"applied_gyro_{key}", cal.get(f"gyro_{key}"))

    lines = [f"  applied ({cal.get('method')}, status {cal.get('status')}; accelerometer {cal.get('accelerometer')}):",
             f"    gyro bias (°/s)  {_vec(g('bias_rad_s'), RAD2DEG)}",
             f"    gyro S           {_pm(g('scale_factor'), g('scale_factor_std'))}",
             f"    gyro G           {_pm(g('nonorthogonality'), g('nonorthogonality_std'))}"]
    if g("misalignment_rad") is not None:
        alpha = _vec(g("misalignment_rad"), RAD2DEG)
        lines.append(f"    gyro α (°)       {alpha}   (its rotation against the accelerometer)")
    if cal.get("accelerometer") != "assumed calibrated":
        lines += [f"    acc. bias (m/s²) {_vec(cal.get('acc_bias_m_s2'))}",
                  f"    acc. S           {_vec(cal.get('acc_scale_factor'))}",
                  f"    acc. G           {_vec(cal.get('acc_nonorthogonality'))}"]
    for reason in cal.get("status_reasons", [])[:2]:
        lines.append("    why: " + (reason if len(reason) <= SHORT else reason[:SHORT - 1] + "…"))
    return lines


def _imucal_lines(rec: RecordingResult) -> list[str]:
    peer = rec.details.get("imucal")
    if not peer:
        return []
    p, cal = peer["parameters"], rec.calibration
    lines = [f"  imucal {peer['version']} on the same file (ours | imucal):"]
    for label, ours, theirs, scale in (("gyro bias (°/s)", "gyro_bias_rad_s", "gyro_bias_rad_s", RAD2DEG),
                                       ("gyro S", "gyro_scale_factor", "gyro_scale_factor", 1.0),
                                       ("gyro G", "gyro_nonorthogonality", "gyro_nonorthogonality", 1.0),
                                       ("acc. bias (m/s²)", "acc_bias_m_s2", "acc_bias_m_s2", 1.0),
                                       ("acc. S", "acc_scale_factor", "acc_scale_factor", 1.0),
                                       ("acc. G", "acc_nonorthogonality", "acc_nonorthogonality", 1.0)):
        lines.append(f"    {label:<17}{_vec(cal.get(ours), scale)} | {_vec(p[theirs], scale)}")
    turn = _vec(peer["gyro_rotation_deg"], 1, 2)
    lines.append(f"    imucal's gyro triad is turned against its accelerometer's by {turn} ° about x, y, z "
                 "(our model has no such rotation)")
    return lines


def text_block(rec: RecordingResult) -> str:
    """One recording's block: commands and exit codes, the parameters applied, the figures per variant."""
    lines = [f"{rec.name} — {rec.reference}; {rec.samples} samples, {rec.duration_s:.1f} s"]
    lines += [_run_line(r) for r in rec.runs]
    lines += _calibration_lines(rec.calibration)
    if rec.plain_reference:
        a, b = rec.plain_reference["rest_s"]
        lines.append(f"  plain reference: gyro bias {_vec(rec.plain_reference['gyro_bias_rad_s'], RAD2DEG)} °/s "
                     f"(rest {a:.1f}–{b:.1f} s)")
    cols = _columns(rec)
    lines.append(f"  {'':<40}" + "".join(f"{VARIANT_LABELS[c]:>11}" for c in cols))
    for key, values in rec.figures.items():
        if key == MAG_KEY:
            continue
        lines.append(f"  {FIGURES[key]:<40}" + "".join(f"{_num(values.get(c, math.nan), _prec(key)):>11}"
                                                      for c in cols))
    if MAG_KEY in rec.figures:
        mag = rec.figures[MAG_KEY]
        status = rec.details.get("magnetometer", {}).get("status", "no result")
        lines.append(f"  {FIGURES[MAG_KEY]} (calib mag: {status}): " + ", ".join(
            f"{VARIANT_LABELS[v]} {_num(mag.get(v, math.nan), 2)}" for v in MAG_VARIANTS))
    for est, pub in rec.details.get("published_raw", {}).items():
        got = "/".join(_num(rec.figures[f"{est}.{m}"]["raw"], 2) for m in pub)
        lines.append(f"  BROAD's published {est} on raw data: {'/'.join(f'{v:.2f}' for v in pub.values())} "
                     f"(total/heading/inclination °); here {got}")
    if rec.kind in ("imu_tk", "imucal", "xio"):
        d = rec.details
        lines.append(f"  {d['static_intervals']} static intervals, {d['moves']} moves, {d['rest_samples']} rest "
                     "samples scored")
    lines += _imucal_lines(rec)
    lines += [f"  note: {n}" for n in rec.notes]
    lines.append(f"  ({rec.seconds:.0f} s)")
    return "\n".join(lines)


def text_medians(v: MeasuredValidation) -> str:
    """The medians over the BROAD trials (negative: the calibration helped)."""
    if not v.medians:
        return "no BROAD trial was scored: no medians"
    n = sum(r.kind == "broad" for r in v.recordings)
    lines = [f"BROAD, {n} trial(s): median change of each figure over the trials (%, negative = better)",
             f"  {'':<40}" + "".join(f"{label:>22}" for _, label in MEDIAN_COLUMNS) + f"{'full worse than raw':>22}"]
    for key, m in v.medians.items():
        if key == MAG_KEY:
            continue
        worse = (f"{m['full_worse_than_raw']:.0f} of {m['full_trials']:.0f}" if "full_trials" in m else "—")
        lines.append(f"  {FIGURES[key]:<40}" + "".join(f"{_pct(m.get(c)):>22}" for c, _ in MEDIAN_COLUMNS)
                     + f"{worse:>22}")
    m = v.medians.get(MAG_KEY, {})
    if "mag_calibrated_vs_raw_pct" in m:
        lines.append(f"  {FIGURES[MAG_KEY]}: calib mag vs raw {m['mag_calibrated_vs_raw_pct']:+.1f} %, worse on "
                     f"{m['mag_calibrated_worse_than_raw']:.0f} of {m['mag_calibrated_trials']:.0f}")
    return "\n".join(lines)


# ------------------------------------------------------------------ Markdown
def _md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    def row(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    return [row(header), "|" + "---|" * len(header), *(row(r) for r in rows)]


def _published_agreement(broad: list[RecordingResult]) -> str:
    """How far the raw-data Madgwick/Mahony figures are from BROAD's published ones (the harness's own check)."""
    diffs = [abs(r.figures[f"{est}.{m}"]["raw"] - p) for r in broad
             for est, pub in r.details.get("published_raw", {}).items() for m, p in pub.items()]
    if not diffs:
        return ""
    trials = sum(bool(r.details.get("published_raw")) for r in broad)
    return (f"On the raw data the Madgwick (C form) and Mahony RMSEs are within {max(diffs):.2f}° of BROAD's published "
            f"values ({len(diffs)} numbers on {trials} trials): the scoring is BROAD's.")


def _runs_cell(rec: RecordingResult, verb: str) -> str:
    runs = [r for r in rec.runs if r.command[1] == verb]
    return " → ".join(str(r.exit_code) + (" (acc. calibrated)" if "--accelerometer" in r.command else "")
                      for r in runs) or "—"


def _applied_cell(c: dict) -> str:
    """How many of the six S, G ``calib apply`` applied and how many the session determined ("all" in a file
    without an applied block: every estimate is applied)."""
    if "gyro_sg_applied" not in c:
        return "all" if c else "—"
    return f"{sum(c['gyro_sg_applied'])} of 6 (determined {sum(c.get('gyro_sg_determined') or [])})"


def _md_broad(v: MeasuredValidation) -> list[str]:
    broad = [r for r in v.recordings if r.kind == "broad"]
    if not broad:
        return []
    out = ["## BROAD trials", "", "What `calib run` did on each trial (exit codes in order; the retry is "
           "`--accelerometer calibrated`), the motion it found, its estimate of S and G, and what `calib apply` "
           "applied of them:", ""]
    rows = []
    for r in broad:
        c = r.calibration
        rows.append([r.name.split("/")[-1], _runs_cell(r, "run"), str(c.get("status", "—")), str(c.get("method", "—")),
                     _pm(c.get("gyro_scale_factor"), c.get("gyro_scale_factor_std"), 3),
                     _pm(c.get("gyro_nonorthogonality"), c.get("gyro_nonorthogonality_std"), 3),
                     str(c.get("motion") or "—"), _applied_cell(c),
                     f"{_runs_cell(r, 'mag')} ({r.details.get('magnetometer', {}).get('status', '—')})"])
    out += _md_table(["trial", "calib run exit", "status", "method", "gyro S ± σ", "gyro G ± σ", "motion",
                      "S, G applied", "calib mag exit"], rows)
    agreement = _published_agreement(broad)
    if agreement:
        out += ["", agreement]
    for key in FIGURES:
        if not any(key in r.figures for r in broad):
            continue
        cols = MAG_VARIANTS if key == MAG_KEY else VARIANTS
        out += ["", f"### {FIGURES[key]}", ""]
        out += _md_table(["trial", *(VARIANT_LABELS[c] for c in cols)],
                         [[r.name.split("/")[-1], *(_num(r.figures[key].get(c, math.nan), 2) for c in cols)]
                          for r in broad if key in r.figures])
    return out


def _md_medians(v: MeasuredValidation) -> list[str]:
    if not v.medians:
        return []
    rows = []
    for key, m in v.medians.items():
        if key == MAG_KEY:
            worse = f"{m.get('mag_calibrated_worse_than_raw', 0):.0f} of {m.get('mag_calibrated_trials', 0):.0f}"
            rows.append([FIGURES[key] + " — calib mag vs raw", "—", _pct(m.get("mag_calibrated_vs_raw_pct")), "—",
                         worse])
            continue
        rows.append([FIGURES[key], *(_pct(m.get(c)) for c, _ in MEDIAN_COLUMNS),
                     f"{m.get('full_worse_than_raw', 0):.0f} of {m.get('full_trials', 0):.0f}"])
    return ["## Medians over the BROAD trials", "", "Median over the trials of the change of each figure "
            "(%, negative: better), and on how many trials the full calibration is worse than the raw data:", "",
            *_md_table(["figure", *(label for _, label in MEDIAN_COLUMNS), "full worse than raw"], rows)]


def _md_sessions(v: MeasuredValidation) -> list[str]:
    out = []
    for r in (r for r in v.recordings if r.kind != "broad"):
        cols = _columns(r)
        c = r.calibration
        d = r.details
        out += ["", f"## {r.name} — {r.reference}", "",
                f"`calib run` exit {_runs_cell(r, 'run')}, status {c.get('status', '—')} ({c.get('method', '—')}); "
                f"{d['static_intervals']} static intervals, {d['moves']} moves, {d['rest_samples']} rest samples.", ""]
        refused = [x for x in r.runs if x.command[1] == "run" and x.exit_code not in (0, 1)]
        if not c and refused:
            out += [f"`calib run` refused: {refused[-1].message}", ""]
        out += _md_table(["figure", *(VARIANT_LABELS[x] for x in cols)],
                         [[FIGURES[k], *(_num(vs.get(x, math.nan), _prec(k)) for x in cols)]
                          for k, vs in r.figures.items()])
        peer = d.get("imucal")
        if peer:
            out += ["", f"Parameters, ours beside imucal {peer['version']} (gyro bias °/s):", ""]
            out += _md_table(["parameter", "ours", "imucal"], [
                [label, _vec(c.get(key), s), _vec(peer["parameters"][key], s)]
                for label, key, s in (("gyro bias", "gyro_bias_rad_s", RAD2DEG), ("gyro S", "gyro_scale_factor", 1.0),
                                      ("gyro G", "gyro_nonorthogonality", 1.0),
                                      ("acc. bias (m/s²)", "acc_bias_m_s2", 1.0),
                                      ("acc. S", "acc_scale_factor", 1.0), ("acc. G", "acc_nonorthogonality", 1.0))])
        out += [f"\n{n}" for n in ([f"Note: {x}" for x in r.notes])]
    return out


def markdown(v: MeasuredValidation, stamp: str = "") -> str:
    """The result as Markdown: the stamp, the medians, the BROAD tables, one section per other recording."""
    lines = ["# Measured-data validation: what the user does next", ""]
    if stamp:
        lines += [stamp, ""]
    lines += ["Generated by the measured-data harness (`python -m calib.scoring.measured`); variants: raw, "
              "bias only (the gyro bias `calib run` reported), full (the file `calib apply` wrote), plain ref. "
              "(S = G = 0, the gyro bias averaged over the first rest).", ""]
    names = {"broad" if r.kind == "broad" else r.name for r in v.recordings}
    lines += ["Data: " + "; ".join(text for key, text in SOURCES.items() if key in names) + ".", ""]
    lines += _md_medians(v)
    lines += [""] + _md_broad(v)
    lines += _md_sessions(v)
    if v.failed:
        lines += ["", "Not scored: " + "; ".join(v.failed)]
    lines += ["", f"Run time {v.seconds:.0f} s wall, {v.cpu_seconds:.0f} s CPU (calib {v.calib_version})."]
    return "\n".join(lines) + "\n"
