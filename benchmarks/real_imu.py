"""Calibrating real consumer IMUs: the two results pages behind docs/real_imu.md, each rendered from its template.

    python benchmarks/real_imu.py --part simulated [--seeds 60] [--gyrosim-seeds 20] --out real_imu_simulated.md
    python benchmarks/real_imu.py --part measured --out real_imu_measured.md

(``python -m benchmarks.results --only real_imu_simulated,real_imu_measured`` runs both and stamps them.)

``simulated`` (benchmarks/real_imu_simulated_template.md): noise-free input (independent generator); Monte Carlo with
a raw accelerometer (independent generator and gyrosim, 20–60 seeds); the hand-blind filter with a hand; speed
(``calib lab bench``).  ``measured`` (benchmarks/real_imu_measured_template.md), from ``$GYROSIM_DATA`` (default
../shared/data): imucal's Ferraris session side by side with imucal 2.6 (the optional ``peers`` extra:
``pip install .[peers]``), imu_tk's Xsens session, BROAD, x-io Fusion.  Each section says how it was computed;
absent data or peers are reported as such.  The hand-aware filter on the same recordings is benchmarks/hand_measured.py.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import sys
import time
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the independent generator lives with the tests

import independent_generator as ig  # noqa: E402

from gyrosim.errors import GyrosimError  # noqa: E402
from gyrosim.loaders import available_datasets, load_dataset  # noqa: E402
from gyrosim.recording import Recording  # noqa: E402

from calib.session.paper import calibrate  # noqa: E402
from calib.session.residuals import compensated, gravity_direction_errors, integrated_turns, pose_gravity_residuals  # noqa: E402

G0 = 9.80665
RAW = {"acc_bias_g": (0.060, -0.055, 0.070), "acc_scale": (0.02, -0.025, 0.03), "acc_nonortho": (0.01, -0.012, 0.015)}
DATASHEET = {"gyro_noise_deg_s": 0.1, "acc_noise_g": 0.003}
NAMES = ["b_x", "b_y", "b_z", "S_x", "S_y", "S_z", "G_x", "G_y", "G_z",
         "acc b_x", "acc b_y", "acc b_z", "acc S_x", "acc S_y", "acc S_z", "acc G_x", "acc G_y", "acc G_z"]


def _rec(d: dict) -> Recording:
    return Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0})


def _truth(d: dict) -> np.ndarray:
    return np.concatenate([d["bias_rad_s"], d["scale_factor"], d["nonorthogonality"], d["acc_bias_m_s2"],
                           d["acc_scale_factor"], d["acc_nonorthogonality"]])


def noise_free() -> str:
    rows = ["| schedule | gyro S, G max error | gyro bias max error (rad/s) | accelerometer S, G max error | "
            "accelerometer bias max error (m/s²) | status |", "|---|---|---|---|---|---|"]
    for name in ("STEPS", "MULTIPOSE_STEPS"):
        d = ig.generate_arrays(steps=getattr(ig, name), gyro_noise_deg_s=0.0, acc_noise_g=0.0, **RAW)
        c = calibrate(_rec(d), "kf_joint")
        e = np.abs(c.parameters() - _truth(d))
        rows.append(
            f"| {name} | {e[3:9].max():.1e} | {e[0:3].max():.1e} | {e[12:18].max():.1e} | {e[9:12].max():.1e} | "
            f"{c.status} |"
        )
    return "\n".join(rows)


def mc_independent(seeds: int) -> tuple[str, dict]:
    out = {}
    rows = [
        "| schedule | seeds | NEES (18 parameters) [95 % band] | err/σ RMS: gyro b, S, G | err/σ RMS: accelerometer "
        "b, S, G | gyro S, G RMS error: raw-estimate / calibrated-accelerometer case |",
        "|---|---|---|---|---|---|",
    ]
    for name in ("STEPS", "MULTIPOSE_STEPS"):
        kin = ig.kinematics(100.0, getattr(ig, name))
        errs, zs, nees, ref = [], [], [], []
        for s in range(1000, 1000 + seeds):
            d = ig.generate_arrays(seed=s, kin=kin, **DATASHEET, **RAW)
            c = calibrate(_rec(d), "kf_joint", keep_history=False)
            e = c.parameters() - _truth(d)
            errs.append(e)
            zs.append(e / np.sqrt(np.diag(c.covariance)))
            nees.append(e @ np.linalg.solve(c.covariance, e))
            clean = ig.generate_arrays(seed=s, kin=kin, **DATASHEET)
            cp = calibrate(_rec(clean), "kf_session_r", accelerometer="calibrated", keep_history=False)
            ref.append(np.r_[cp.scale_factor - clean["scale_factor"], cp.nonorthogonality - clean["nonorthogonality"]])
        errs, zs, nees, ref = map(np.array, (errs, zs, nees, ref))
        z = np.sqrt(np.mean(zs**2, axis=0))
        ratio = np.sqrt(np.mean(errs[:, 3:9] ** 2, axis=0)) / np.sqrt(np.mean(ref**2, axis=0))
        band = stats.chi2.ppf([0.025, 0.975], 18 * seeds) / seeds
        out[name] = {"z_rms": z.tolist(), "nees": float(nees.mean()), "band": band.tolist(), "ratio": ratio.tolist()}
        fmt = lambda v: ", ".join(f"{x:.2f}" for x in v)  # noqa: E731
        rows.append(f"| {name} | {seeds} | {nees.mean():.2f} [{band[0]:.2f}, {band[1]:.2f}] | {fmt(z[:9])} | "
                    f"{fmt(z[9:])} | {fmt(ratio)} |")
    return "\n".join(rows), out


def mc_gyrosim(seeds: int) -> str:
    from calib.scoring.montecarlo import monte_carlo

    blocks = []
    for schedule in ("zhou2020", "zhou2020_multipose"):
        # calib run's filter (kf_session) in both modes: 21 states with the raw accelerometer, 9 with it calibrated
        r = monte_carlo(schedule, "ideal", "mpu9250_linear", seeds, methods=("kf_session",), accelerometer="estimate")
        c = monte_carlo(schedule, "ideal", "mpu9250_linear", seeds, methods=("kf_session",), accelerometer="calibrated",
                        calibrated_accelerometer=True)
        blocks.append("```\n" + r.table() + "\n```")
        ratio = r.methods["kf_session"].rmse[3:9] / c.methods["kf_session"].rmse[3:9]
        blocks.append("gyro S, G RMS error, raw accelerometer estimated / calibrated accelerometer (calib run's "
                      "filter, 9 states) on "
                      f"{schedule}: {', '.join(f'{x:.2f}' for x in ratio)}")
    return "\n\n".join(blocks)


def hands(seeds: int = 5) -> str:
    """The known limit: what the hand does to σ (the hand-aware estimator's subject), measured, not hidden."""
    from gyrosim.calibration import truth_calibration
    from gyrosim.simulate import simulate

    rows = ["| hand | seeds | status ok / inconsistent / diverged | gyro S, G: RMS error | gyro S, G: err/σ RMS | "
            "accelerometer b, S, G: err/σ RMS |", "|---|---|---|---|---|---|"]
    for hand in ("ideal", "steady", "typical"):
        errs, zs, st = [], [], []
        for seed in range(seeds):
            rec = simulate("zhou2020", hand, "mpu9250_linear", 100.0, seed=seed)
            c = calibrate(rec, "kf_joint", keep_history=False)
            e = c.parameters() - truth_calibration(rec).parameters()
            errs.append(e)
            zs.append(e / np.sqrt(np.diag(c.covariance)))
            st.append(c.status)
        errs, zs = np.array(errs), np.array(zs)
        counts = "/".join(str(st.count(k)) for k in ("ok", "inconsistent", "diverged"))
        rows.append(f"| {hand} | {seeds} | {counts} | {np.sqrt(np.mean(errs[:, 3:9] ** 2)):.1e} | "
                    f"{np.sqrt(np.mean(zs[:, 3:9] ** 2)):.1f} | {np.sqrt(np.mean(zs[:, 9:] ** 2)):.1f} |")
    return "\n".join(rows)


def bench() -> str:
    from calib.scoring.speed import run_bench

    buf = io.StringIO()
    with redirect_stdout(buf):
        run_bench(batch=20, repeats=3)
    return "```\n" + buf.getvalue() + "```"


# ------------------------------------------------------------------ measured data
def _fmt_vec(v, scale=1.0, prec=4):
    return ", ".join(f"{x * scale:+.{prec}f}" for x in v)


def ferraris() -> str:
    if "imucal_ferraris" not in available_datasets():
        return "imucal's Ferraris session is not in the data folder: skipped."
    from gyrosim.loaders import data_root

    rec = load_dataset("imucal_ferraris")
    seg = rec.meta["segments"]
    lines = []
    # the table's "kf" / "iterated" columns: calib run's filter (kf_session / iterated_session)
    cals = {m: calibrate(rec, f"{m}_session") for m in ("kf", "iterated")}
    ours = cals["kf"]
    lines.append(f"`calib run dataset:imucal_ferraris` (kf): status **{ours.status}** — "
                 + "; ".join(w for w in ours.warnings if w.startswith(("inconsistent", "diverged"))))
    lines.append("")
    try:
        import pandas as pd
        from imucal import FerrarisCalibration, ferraris_regions_from_section_list
        from imucal import __version__ as imucal_version
    except ImportError:
        return "\n".join(lines + ["imucal is not installed (`pip install .[peers]`): no side-by-side table."])
    root = data_root() / "imucal_ferraris"
    df = pd.read_csv(root / "example_ferraris_session.csv")
    sl = pd.DataFrame(json.loads((root / "example_ferraris_session_list.json").read_text())).T
    info = FerrarisCalibration(grav=G0).compute(ferraris_regions_from_section_list(df, sl), 102.4, "m/s^2", "deg/s")
    from scipy.linalg import polar

    a_mat = info.K_a @ info.R_a
    u, p = polar(a_mat, side="left")   # A = P U: P the symmetric part (our M_a), U imucal's frame → ours
    b_in_ours = info.K_g @ info.R_g @ u.T
    sym = 0.5 * (b_in_ours + b_in_ours.T)
    anti = 0.5 * (b_in_ours - b_in_ours.T)
    imucal_vec = np.concatenate([np.radians(info.b_g), np.diag(sym) - 1, [sym[1, 2], sym[0, 2], sym[0, 1]],
                                 info.b_a, np.diag(p) - 1, [p[1, 2], p[0, 2], p[0, 1]]])
    lines.append(f"imucal {imucal_version} (`FerrarisCalibration(grav=9.80665)`, the session's own section list) "
                 "against ours.  imucal fits a general 3×3 matrix per triad (K R) in the frame of its six poses; "
                 "ours is symmetric in the accelerometer's own frame, so imucal's accelerometer matrix is split "
                 "A = P U (polar decomposition): P is comparable with our I + S_a + N(G_a), U turns imucal's frame "
                 "into ours, and imucal's gyro matrix in our frame, K_g R_g Uᵀ, has a symmetric part (comparable "
                 "with I + S_g + N(G_g)) and an antisymmetric part: a rotation of the gyro triad against the "
                 f"accelerometer's of {np.degrees(anti[2, 1]):+.2f}°, {np.degrees(anti[0, 2]):+.2f}°, "
                 f"{np.degrees(anti[1, 0]):+.2f}° about x, y, z, which our model does not have.  imucal's "
                 f"g-sensitivity K_ga (max |·| {np.abs(info.K_ga).max():.1e} °/s per m/s²) is not compared.")
    lines.append("")
    lines.append("| parameter | imucal | ours kf ± σ | (kf − imucal)/σ | ours iterated ± σ | (iterated − imucal)/σ |")
    lines.append("|---|---|---|---|---|---|")
    scale = np.array([180 / math.pi] * 3 + [1] * 6 + [1] * 3 + [1] * 6)
    units = ["°/s"] * 3 + [""] * 6 + ["m/s²"] * 3 + [""] * 6
    for i, name in enumerate(NAMES):
        cells = [f"{name} {units[i]}".strip(), f"{imucal_vec[i] * scale[i]:+.5f}"]
        for m in ("kf", "iterated"):
            v, s = cals[m].parameters()[i], math.sqrt(cals[m].covariance[i, i])
            cells += [f"{v * scale[i]:+.5f} ± {s * scale[i]:.5f}", f"{(v - imucal_vec[i]) / s:+.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    # residuals each calibration leaves
    poses = [(seg[k]["start"], seg[k]["end"]) for k in ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")]
    turns = [(seg[k]["start"], seg[k]["end"]) for k in ("x_rot", "y_rot", "z_rot")]
    raw = compensated(rec, None, ours.bias_rad_s)
    imu_acc, imu_gyr = info.calibrate(
        acc=rec.acc_m_s2, gyr=np.degrees(rec.gyro_rad_s), acc_unit="m/s^2", gyr_unit="deg/s"
    )
    imucal_rec = rec.with_signals(acc_m_s2=imu_acc, gyro_rad_s=np.radians(imu_gyr))
    versions = {"raw (gyro static bias removed)": raw, "imucal": imucal_rec, "ours (kf)": ours.compensate(rec),
                "ours (iterated)": cals["iterated"].compensate(rec)}
    lines.append(
        "Residual |f| − g (mg) at the six poses, and the angle each 360° turn integrates to (imucal's measure, "
        "Σ ω Δt along the turn's axis; the protocol turns by −360°):"
    )
    lines.append("")
    lines.append("| calibration | " + " | ".join(k for k in ("x+", "x−", "y+", "y−", "z+", "z−")) +
                 " | RMS | x turn (°) | y turn (°) | z turn (°) |")
    lines.append("|---|" + "---|" * 10)
    for label, r in versions.items():
        res = pose_gravity_residuals(r, poses, G0)[:, 0] * 1000 / G0
        ang = integrated_turns(r, turns)
        lines.append(f"| {label} | " + " | ".join(f"{x:+.1f}" for x in res) + f" | {np.sqrt(np.mean(res**2)):.1f} | "
                     + " | ".join(f"{ang[i, i]:+.2f}" for i in range(3)) + " |")
    lines.append("")
    lines.append("Gravity-direction error across the hand moves between consecutive poses (the compensated gyro "
                 "carries pose i's gravity direction to pose i+1; degrees).  imucal never sees these moves; ours uses "
                 "them (they are part of the session), so for ours this is an in-sample check:")
    lines.append("")
    lines.append("| calibration | x+→x− | x−→y+ | y+→y− | y−→z+ | z+→z− | RMS |")
    lines.append("|---|---|---|---|---|---|---|")
    for label, r in versions.items():
        e = gravity_direction_errors(r, poses)
        lines.append(f"| {label} | " + " | ".join(f"{x:.2f}" for x in e) + f" | {np.sqrt(np.mean(e**2)):.2f} |")
    return "\n".join(lines)


def _rest_table(rec, cal, label_before="before (raw, gyro static bias removed)") -> tuple[list[str], np.ndarray,
                                                                                         np.ndarray]:
    ranges = [tuple(r) for r in _rest_ranges(rec, cal)]
    before = compensated(rec, None, cal.bias_rad_s)
    after = cal.compensate(rec)
    rb = pose_gravity_residuals(before, ranges, G0)
    ra = pose_gravity_residuals(after, ranges, G0)
    gb = gravity_direction_errors(before, ranges)
    ga = gravity_direction_errors(after, ranges)
    return ranges, np.c_[rb[:, 0], ra[:, 0]], np.c_[gb, ga]


def _rest_ranges(rec, cal):
    t = rec.t_s
    return [(int(np.searchsorted(t, a)), int(np.searchsorted(t, b)) + 1) for a, b in cal.diagnostics["rest_segments"]
            if b - a >= 1.0]


def imu_tk() -> str:
    if "imu_tk_xsens" not in available_datasets():
        return "imu_tk's Xsens session is not in the data folder: skipped."
    rec = load_dataset("imu_tk_xsens")
    cal = calibrate(rec, "kf_joint")
    ranges, res, ang = _rest_table(rec, cal)
    mg = res * 1000 / G0
    lines = [
        f"`calib run dataset:imu_tk_xsens`: status **{cal.status}**; "
        + "; ".join(w for w in cal.warnings if w.startswith(("inconsistent", "diverged"))),
        "",
        "Estimate (the loader's nominal: gyro (c − 32768)/6258 rad/s, accelerometer scaled so the first 40 s read g):",
        "",
        "| | x | y | z |",
        "|---|---|---|---|",
    ]
    for triad, kind, label, sc in (
        ("gyro", "bias", "gyro bias (°/s)", 180 / math.pi),
        ("gyro", "scale_factor", "gyro S", 1),
        ("gyro", "nonorthogonality", "gyro G", 1),
        ("accelerometer", "bias", "acc bias (mg)", 1000 / G0),
        ("accelerometer", "scale_factor", "acc S", 1),
        ("accelerometer", "nonorthogonality", "acc G", 1),
    ):
        v, s = cal.value(triad, kind) * sc, cal.std(triad, kind) * sc
        lines.append(f"| {label} | " + " | ".join(f"{a:+.5f} ± {b:.5f}" for a, b in zip(v, s)) + " |")
    lines += [
        "",
        f"{len(ranges)} rest poses.  |f| − g (mg) and the gravity-direction error across each move between "
        "consecutive poses (°), before and after:",
        "",
        "| | |f| − g RMS | |f| − g max | direction error RMS | direction error max |",
        "|---|---|---|---|---|",
        f"| before | {np.sqrt(np.mean(mg[:, 0] ** 2)):.1f} | {np.abs(mg[:, 0]).max():.1f} | "
        f"{np.sqrt(np.mean(ang[:, 0] ** 2)):.2f} | {ang[:, 0].max():.2f} |",
        f"| after | {np.sqrt(np.mean(mg[:, 1] ** 2)):.1f} | {np.abs(mg[:, 1]).max():.1f} | "
        f"{np.sqrt(np.mean(ang[:, 1] ** 2)):.2f} | {ang[:, 1].max():.2f} |",
        "",
        "<details><summary>every pose</summary>",
        "",
        "| pose | t (s) | |f| − g before (mg) | after (mg) | direction error to the next pose before (°) | after (°) |",
        "|---|---|---|---|---|---|",
    ]
    for i, (a, b) in enumerate(ranges):
        d = f"{ang[i, 0]:.2f} | {ang[i, 1]:.2f}" if i < len(ang) else "— | —"
        lines.append(f"| {i + 1} | {rec.t_s[a]:.1f}–{rec.t_s[b - 1]:.1f} | {mg[i, 0]:+.1f} | {mg[i, 1]:+.1f} | {d} |")
    lines += ["", "</details>"]
    return "\n".join(lines)


def broad() -> str:
    trials = [t for t in available_datasets() if t.startswith("broad/")]
    if not trials:
        return "BROAD is not in the data folder: skipped."
    lines = [
        "| trial | status | accelerometer bias (mg) | accelerometer S | |f| − g at rest before → after (mg, RMS) | "
        "gravity direction vs optical truth at rest, before → after (°, RMS) |",
        "|---|---|---|---|---|---|",
    ]
    for trial in trials:
        rec = load_dataset(trial)
        try:
            cal = calibrate(rec, "kf_joint")
        except GyrosimError as exc:
            lines.append(f"| {trial.split('/')[1]} | refused: {str(exc)[:160]}… | | | | |")
            continue
        ranges = [tuple(r) for r in _rest_ranges(rec, cal)]
        before, after = compensated(rec, None, cal.bias_rad_s), cal.compensate(rec)
        rb = pose_gravity_residuals(before, ranges, G0)[:, 0] * 1000 / G0
        ra = pose_gravity_residuals(after, ranges, G0)[:, 0] * 1000 / G0
        q = rec.truth.quat_nb
        from gyrosim.rotations import quat_conjugate, quat_rotate

        def truth_angle(r):
            errs = []
            for a, b in ranges:
                ok = np.all(np.isfinite(q[a:b]), axis=1)
                if not ok.any():
                    continue
                g_b = quat_rotate(quat_conjugate(q[a:b][ok]), np.array([0.0, 0.0, 1.0])).mean(axis=0)
                f = r.acc_m_s2[a:b][ok].mean(axis=0)
                errs.append(np.degrees(np.arccos(np.clip(g_b @ f / np.linalg.norm(g_b) / np.linalg.norm(f), -1, 1))))
            return np.sqrt(np.mean(np.square(errs))) if errs else float("nan")

        lines.append(f"| {trial.split('/')[1]} | {cal.status} | "
                     f"{_fmt_vec(cal.value('accelerometer', 'bias'), 1000 / G0, 1)} "
                     f"| {_fmt_vec(cal.value('accelerometer', 'scale_factor'), 1, 4)} | "
                     f"{np.sqrt(np.mean(rb**2)):.1f} → {np.sqrt(np.mean(ra**2)):.1f} | "
                     f"{truth_angle(before):.2f} → {truth_angle(after):.2f} |")
    return "\n".join(lines)


def xio() -> str:
    if "xio_fusion" not in available_datasets():
        return "x-io Fusion's recording is not in the data folder: skipped."
    from calib.inputs import KF, prepare_recording

    loaded = prepare_recording(load_dataset("xio_fusion"), KF)  # what calib run does: its 10 two-sample gaps bridged
    rec = loaded.recording
    lines = [f"Input: {'; '.join(loaded.report.warnings)}."]
    for mode in ("estimate", "calibrated"):
        try:
            cal = calibrate(rec, ("kf_joint" if mode == "estimate" else "kf_session_r"), accelerometer=mode)
        except GyrosimError as exc:
            lines.append(f"`calib run dataset:xio_fusion --accelerometer {mode}`: refused — {exc}")
            continue
        acc = (f"accelerometer bias {_fmt_vec(cal.value('accelerometer', 'bias'), 1000 / G0, 1)} mg, S "
               f"{_fmt_vec(cal.value('accelerometer', 'scale_factor'))}; " if mode == "estimate" else "")
        lines.append(f"`calib run dataset:xio_fusion --accelerometer {mode}`: status **{cal.status}**; {acc}gyro S "
                     f"{_fmt_vec(cal.scale_factor)}; " + "; ".join(cal.warnings))
    return "\n\n".join(lines)


PARTS = {
    "simulated": ("real_imu_simulated_template.md", ("noise_free", "mc_independent", "mc_gyrosim", "hands", "bench")),
    "measured": ("real_imu_measured_template.md", ("ferraris", "imu_tk", "broad", "xio")),
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=tuple(PARTS), required=True, help="which results page to write")
    ap.add_argument("--seeds", type=int, default=60, help="seeds of the independent-generator Monte Carlo")
    ap.add_argument("--gyrosim-seeds", type=int, default=20, help="seeds of the gyrosim Monte Carlo")
    ap.add_argument("--out", required=True, help="the Markdown page to write")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    sections = {"noise_free": noise_free, "mc_independent": lambda: mc_independent(args.seeds)[0],
                "mc_gyrosim": lambda: mc_gyrosim(args.gyrosim_seeds), "hands": hands, "bench": bench,
                "ferraris": ferraris, "imu_tk": imu_tk, "broad": broad, "xio": xio}
    template_name, names = PARTS[args.part]
    parts = {}
    for name in names:
        print(f"… {name}", file=sys.stderr, flush=True)
        parts[name] = sections[name]()
    template = (ROOT / "benchmarks" / template_name).read_text()
    text = template.format(**parts, seeds=args.seeds, gyrosim_seeds=args.gyrosim_seeds,
                           band=1.96 / math.sqrt(2 * args.seeds), minutes=(time.perf_counter() - t0) / 60)
    Path(args.out).write_text(text)
    print(f"wrote {args.out} in {(time.perf_counter() - t0) / 60:.1f} min", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
