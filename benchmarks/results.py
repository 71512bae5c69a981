"""Every measured result in docs/results/: the command that writes it, its files, and how long it takes.

    python -m benchmarks.results --list                  # every result: duration, files, the code that wrote them
    python -m benchmarks.results --only hand_measured    # regenerate one (or several: a,b,c)
    python -m benchmarks.results --quick                 # every result that takes under ~10 min on one core
    python -m benchmarks.results                         # all of them (hours: the hand campaigns)
    python -m benchmarks.results --render                # only re-render the guides' result snippets

Run from the checkout's root.  Each result runs its steps in order (the interpreter of this process for
``python``, the checkout on ``PYTHONPATH``, ``OMP_NUM_THREADS=1``), then stamps every file it wrote with the commit,
whether the tree had changes outside docs/, the exact command lines, the date, the wall time and the exit codes
(:mod:`benchmarks.provenance`).  A step whose stdout is the result is captured into a Markdown file.  Exit code 1
of a step is the project's "done, but not ok" (a check that failed is part of the result); 2 or more stops the
result.  Afterwards every ``<!-- result:FILE -->…<!-- /result -->`` block of the guides is re-rendered from the
file it names (:mod:`benchmarks.snippets`), so a guide never carries a number typed by hand.

Durations are rough, on one core of the project's shared 2-core machine.  Results that read the measured
recordings need ``$GYROSIM_DATA`` (default ../shared/data) and are skipped without it; results that need a peer
package say which extra installs it.
"""

from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

if __package__ in (None, ""):   # python benchmarks/results.py
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks import provenance, snippets  # noqa: E402

ROOT = provenance.ROOT
RESULTS = ROOT / "docs" / "results"
QUICK_MINUTES = 10.0


@dataclass(frozen=True)
class Step:
    """One command line; ``{results}`` is docs/results, ``{scratch}`` this result's temporary folder.
    ``capture``: the file under docs/results its stdout is written to (``fmt`` "text": a fenced block, "markdown":
    as printed, "json": the JSON it prints)."""

    command: str
    capture: str | None = None
    fmt: str = "text"


@dataclass(frozen=True)
class Result:
    """A result: its steps, the files they write under docs/results, and the rough duration on one core."""

    name: str
    title: str
    steps: tuple[Step, ...]
    outputs: tuple[str, ...]
    minutes: float
    data: bool = False                 # reads the measured recordings ($GYROSIM_DATA)
    inputs: tuple[str, ...] = ()       # other results' files it reads (their stamps are recorded in this one's)
    note: str = ""

    @property
    def quick(self) -> bool:
        return self.minutes <= QUICK_MINUTES

    def commands(self) -> list[str]:
        return [s.command.format(results="docs/results", scratch="$SCRATCH") for s in self.steps]


def S(command: str, capture: str | None = None, fmt: str = "text") -> Step:
    return Step(" ".join(command.split()), capture, fmt)


HC = "python benchmarks/hand_campaign.py"
NF = ("calib lab northfind-mc --sensor {sensor} --latitudes 0,45,70 --seeds {seeds} {extra} "
      "--json {{results}}/{out}.json")

REGISTRY: tuple[Result, ...] = (
    # ------------------------------------------------------------------ the hand (docs/hand.md)
    Result("hand_zhou2020_sim_consumer", "kf_hand campaign, consumer sensor (accelerometer calibrated), 4 hands",
           (S(f"{HC} --sensor zhou2020_sim_consumer --methods kf_hand --seeds 50 "
              "--out {results}/hand_zhou2020_sim_consumer.json"),),
           ("hand_zhou2020_sim_consumer.json",), 40),
    Result("hand_mpu9250", "kf_hand campaign, MPU-9250 (accelerometer calibrated), 4 hands",
           (S(f"{HC} --sensor mpu9250 --methods kf_hand --seeds 50 --out {{results}}/hand_mpu9250.json"),),
           ("hand_mpu9250.json",), 40),
    Result("hand_kf_zhou2020_sim_consumer", "the paper's kf beside kf_hand, consumer sensor",
           (S(f"{HC} --sensor zhou2020_sim_consumer --methods kf --hands ideal --seeds 50 "
              "--out {results}/hand_kf_zhou2020_sim_consumer.json"),
            S(f"{HC} --sensor zhou2020_sim_consumer --methods kf --hands steady,typical,shaky --seeds 10 "
              "--out {results}/hand_kf_zhou2020_sim_consumer.json")),
           ("hand_kf_zhou2020_sim_consumer.json",), 12),
    Result("hand_kf_mpu9250", "the paper's kf beside kf_hand, MPU-9250",
           (S(f"{HC} --sensor mpu9250 --methods kf --hands ideal --seeds 50 --out {{results}}/hand_kf_mpu9250.json"),
            S(f"{HC} --sensor mpu9250 --methods kf --hands steady,typical,shaky --seeds 10 "
              "--out {results}/hand_kf_mpu9250.json")),
           ("hand_kf_mpu9250.json",), 12),
    Result("hand_campaign", "method × hand: RMS error, efficiency, NEES of kf_hand and kf (table and plot)",
           (S(f"{HC} --table {{results}}/hand_zhou2020_sim_consumer.json {{results}}/hand_mpu9250.json "
              "{results}/hand_kf_zhou2020_sim_consumer.json {results}/hand_kf_mpu9250.json "
              "--plot {results}/hand_rmse.png", capture="hand_campaign.md", fmt="markdown"),),
           ("hand_campaign.md", "hand_rmse.png"), 0.2,
           inputs=("hand_zhou2020_sim_consumer.json", "hand_mpu9250.json", "hand_kf_zhou2020_sim_consumer.json",
                   "hand_kf_mpu9250.json")),
    Result("hand_joint_zhou2020_sim_consumer", "kf_hand_joint against kf_session, raw consumer sensor, 4 hands",
           (S(f"{HC} --sensor zhou2020_sim_consumer --accelerometer estimate --methods kf_hand_joint,kf_session "
              "--seeds 50 --out {results}/hand_joint_zhou2020_sim_consumer.json"),),
           ("hand_joint_zhou2020_sim_consumer.json",), 45),
    Result("hand_joint_mpu9250", "kf_hand_joint against kf_session, raw MPU-9250, 4 hands",
           (S(f"{HC} --sensor mpu9250 --accelerometer estimate --methods kf_hand_joint,kf_session --seeds 50 "
              "--out {results}/hand_joint_mpu9250.json"),),
           ("hand_joint_mpu9250.json",), 45),
    Result("hand_joint", "raw sensors: kf_hand_joint against kf_session (S, G table, plot; accelerometer table)",
           (S(f"{HC} --table {{results}}/hand_joint_zhou2020_sim_consumer.json {{results}}/hand_joint_mpu9250.json "
              "--plot {results}/hand_joint_rmse.png", capture="hand_joint.md", fmt="markdown"),
            S(f"{HC} --accelerometer-table {{results}}/hand_joint_zhou2020_sim_consumer.json "
              "{results}/hand_joint_mpu9250.json", capture="hand_joint_accelerometer.md", fmt="markdown")),
           ("hand_joint.md", "hand_joint_rmse.png", "hand_joint_accelerometer.md"), 0.2,
           inputs=("hand_joint_zhou2020_sim_consumer.json", "hand_joint_mpu9250.json")),
    Result("hand_bias", "the gyro bias kf_hand reports: err/σ before and after the rest's own σ model",
           (S("python benchmarks/hand_bias_campaign.py --seeds 50 --out {results}/hand_bias.json"),),
           ("hand_bias.json", "hand_bias.md"), 30),
    Result("hand_bias_joint", "the same for kf_hand_joint (raw accelerometer)",
           (S("python benchmarks/hand_bias_campaign.py --seeds 50 --hands ideal,typical --accelerometer estimate "
              "--out {results}/hand_bias_joint.json"),),
           ("hand_bias_joint.json", "hand_bias_joint.md"), 15),
    Result("hand_cross_check_zhou2020_sim_consumer", "the hand cross-check of kf_session's answers, consumer sensor",
           (S("python benchmarks/hand_cross_check_campaign.py --sensor zhou2020_sim_consumer --seeds 50 "
              "--out {results}/hand_cross_check_zhou2020_sim_consumer.json"),),
           ("hand_cross_check_zhou2020_sim_consumer.json",), 20),
    Result("hand_cross_check_mpu9250", "the hand cross-check of kf_session's answers, MPU-9250",
           (S("python benchmarks/hand_cross_check_campaign.py --sensor mpu9250 --seeds 50 "
              "--out {results}/hand_cross_check_mpu9250.json"),),
           ("hand_cross_check_mpu9250.json",), 20),
    Result("hand_cross_check", "wrong 'ok' answers of the hand-blind joint filter, before and after the cross-check",
           (S("python benchmarks/hand_cross_check_campaign.py --table "
              "{results}/hand_cross_check_zhou2020_sim_consumer.json {results}/hand_cross_check_mpu9250.json",
              capture="hand_cross_check.md", fmt="markdown"),),
           ("hand_cross_check.md",), 0.1,
           inputs=("hand_cross_check_zhou2020_sim_consumer.json", "hand_cross_check_mpu9250.json")),
    Result("honest_sigma", "the hand-blind filters' σ with the ideal hand (accelerometer calibrated, 50 seeds)",
           (S("calib lab montecarlo --sensor zhou2020_sim_consumer --calibrated-accelerometer --hand ideal --seeds 50 "
              "--methods kf,kf_session_r", capture="honest_sigma.md"),
            S("calib lab montecarlo --sensor mpu9250 --calibrated-accelerometer --hand ideal --seeds 50 --methods kf",
              capture="honest_sigma.md")),
           ("honest_sigma.md",), 6),
    Result("output_lowpass", "a sensor behind an output low-pass (DLPF) below the noise band: bias and S, G σ",
           (S("python benchmarks/output_lowpass.py --cutoffs 41,20,10,5 --seeds 30 "
              "--out {results}/output_lowpass.json"),
            S("python benchmarks/output_lowpass.py --method kf_hand_joint --cutoffs 10 --seeds 30 "
              "--out {results}/output_lowpass_joint.json"),
            S("python benchmarks/output_lowpass.py --table {results}/output_lowpass.json "
              "{results}/output_lowpass_joint.json", capture="output_lowpass.md", fmt="markdown")),
           ("output_lowpass.json", "output_lowpass_joint.json", "output_lowpass.md"), 7),
    Result("mpu9250_ablation", "which MPU-9250 gyro effect sets kf_hand's excess over the hand-aware bound",
           (S("python benchmarks/mpu9250_ablation.py --seeds 50 --out {results}/mpu9250_ablation.json"),),
           ("mpu9250_ablation.json",), 15),
    Result("mpu9250_warm_ablation", "a warmed-up MPU-9250: which unmodelled effect leaves σ short (200 seeds)",
           (S("python benchmarks/mpu9250_ablation.py --base warmup,g_sensitivity --method kf_hand --seeds 200 "
              "--variants full,-bias_instability,-scale_nonlinearity,-scale_nonlinearity-bias_instability,"
              "-scale_nonlinearity-bias_instability-random_walk,white\\ noise\\ +\\ bandwidth,"
              "white\\ noise\\ +\\ quantization,white\\ noise\\ only --out {results}/mpu9250_warm_ablation.json"),),
           ("mpu9250_warm_ablation.json",), 25),
    Result("mpu9250_ablation_tables", "the two MPU-9250 ablations as tables",
           (S("python benchmarks/mpu9250_ablation.py --table {results}/mpu9250_ablation.json",
              capture="mpu9250_ablation.md", fmt="markdown"),
            S("python benchmarks/mpu9250_ablation.py --table {results}/mpu9250_warm_ablation.json",
              capture="mpu9250_warm_ablation.md", fmt="markdown")),
           ("mpu9250_ablation.md", "mpu9250_warm_ablation.md"), 0.1,
           inputs=("mpu9250_ablation.json", "mpu9250_warm_ablation.json")),
    Result("hand_variants", "hands we did not tune for: each imperfection of the shaky hand switched off",
           (S("python benchmarks/hand_variants.py --seeds 50 --out {results}/hand_variants.json"),),
           ("hand_variants.json",), 70),
    Result("hand_variants_typical", "the same with the typical hand's size",
           (S("python benchmarks/hand_variants.py --base typical --variants sway,wobble "
              "--cells zhou2020_sim_consumer:kf_hand_joint,zhou2020_sim_consumer:kf_hand --seeds 50 "
              "--out {results}/hand_variants_typical.json"),),
           ("hand_variants_typical.json",), 15),
    Result("hand_variants_tables", "the hand variants as tables",
           (S("python benchmarks/hand_variants.py --table {results}/hand_variants.json", capture="hand_variants.md",
              fmt="markdown"),
            S("python benchmarks/hand_variants.py --table {results}/hand_variants_typical.json",
              capture="hand_variants_typical.md", fmt="markdown")),
           ("hand_variants.md", "hand_variants_typical.md"), 0.1,
           inputs=("hand_variants.json", "hand_variants_typical.json")),
    # ------------------------------------------------------------------ measured recordings (docs/real_imu.md)
    Result("hand_measured", "kf_hand and calib run's other methods on every measured recording",
           (S("python benchmarks/hand_measured.py --json {results}/hand_measured.json "
              "--md {results}/hand_measured.md"),),
           ("hand_measured.json", "hand_measured.md"), 4, data=True),
    Result("real_imu_simulated", "the joint gyro + accelerometer calibration on simulated raw sensors, and its speed",
           (S("python benchmarks/real_imu.py --part simulated --seeds 60 --gyrosim-seeds 20 "
              "--out {results}/real_imu_simulated.md"),),
           ("real_imu_simulated.md",), 20),
    Result("false_alarm", "how often calib run's default says not ok while the truth lies within its σ, 50 seeds",
           (S("python benchmarks/false_alarm.py --seeds 50 --out {results}/false_alarm.json"),),
           ("false_alarm.json",), 25,
           note="false_alarm_before.json is the same run on the code before the verdict's rule changed (its stamp "
                "names that commit); it is an input of the table, not regenerated"),
    Result("false_alarm_demo_sensor", "the same on the demo's sensor (zhou2020_sim: an accelerometer with only "
           "noise), 50 seeds",
           (S("python benchmarks/false_alarm.py --seeds 50 --sensor zhou2020_sim "
              "--out {results}/false_alarm_demo_sensor.json"),),
           ("false_alarm_demo_sensor.json",), 6,
           note="false_alarm_demo_sensor_before.json is the same run on the code before a part with nothing to "
                "correct stopped counting as rejected (its stamp names that commit); an input of the table"),
    Result("false_alarm_table", "the false-alarm runs as a table, one row each",
           (S("python benchmarks/false_alarm.py --table {results}/false_alarm_before.json {results}/false_alarm.json "
              "{results}/false_alarm_demo_sensor_before.json {results}/false_alarm_demo_sensor.json "
              "--markdown {results}/false_alarm.md"),),
           ("false_alarm.md",), 0.1, inputs=("false_alarm_before.json", "false_alarm.json",
                                             "false_alarm_demo_sensor_before.json", "false_alarm_demo_sensor.json")),
    Result("sz_ferraris", "imucal's Ferraris session: what pulls the gyro's S_z, per move and per kf_hand variant",
           (S("python benchmarks/sz_ferraris.py", capture="sz_ferraris.md", fmt="markdown"),),
           ("sz_ferraris.md",), 1, data=True),
    Result("compile_floor", "the filter's first compile per numba setting: numba's own share, LLVM's, and what each "
           "setting's code then runs at", (S("python benchmarks/compile_floor.py", capture="compile_floor.md",
                                             fmt="markdown"),), ("compile_floor.md",), 2),
    Result("readme_examples", "every README command run as written in a fresh folder: exit code and wall time",
           (S("python benchmarks/readme_examples.py --out {results}/readme_examples.md"),),
           ("readme_examples.md",), 2),
    Result("measured", "calib run, apply and mag as a user runs them on every measured recording, judged by what "
           "comes next", (S("python -m benchmarks.measured {results}"),), ("measured.json", "measured.md"), 11,
           data=True),
    Result("real_imu_measured", "calib run on the measured recordings, side by side with imucal",
           (S("python benchmarks/real_imu.py --part measured --out {results}/real_imu_measured.md"),),
           ("real_imu_measured.md",), 3, data=True,
           note="imucal's side of the Ferraris table needs the peers extra: pip install .[peers]"),
    # ------------------------------------------------------------------ instruments (docs/instruments.md)
    Result("northfind_mc_fog_4pos", "north-finding error against its limit: FOG, 4 positions, 200 devices per latitude",
           (S(NF.format(sensor="fog_tactical", seeds=200, extra="", out="northfind_mc_fog_4pos"),
              capture="northfind_mc_fog_4pos.md"),),
           ("northfind_mc_fog_4pos.json", "northfind_mc_fog_4pos.md"), 3),
    Result("northfind_mc_fog_2pos", "the same, 2 positions",
           (S(NF.format(sensor="fog_tactical", seeds=200, extra="--positions 2", out="northfind_mc_fog_2pos"),
              capture="northfind_mc_fog_2pos.md"),),
           ("northfind_mc_fog_2pos.json", "northfind_mc_fog_2pos.md"), 2),
    Result("northfind_mc_mpu9250", "the same for a MEMS gyro (50 devices per latitude)",
           (S(NF.format(sensor="mpu9250", seeds=50, extra="", out="northfind_mc_mpu9250"),
              capture="northfind_mc_mpu9250.md"),),
           ("northfind_mc_mpu9250.json", "northfind_mc_mpu9250.md"), 2),
    Result("northfind_unshielded", "the unshielded FOG coil (magnetic sensitivity as shipped), 50 devices",
           (S("calib lab northfind-mc --sensor fog_tactical --shield 1 --latitudes 0,48,70 --seeds 50 "
              "--json {results}/northfind_unshielded.json", capture="northfind_unshielded.md"),),
           ("northfind_unshielded.json", "northfind_unshielded.md"), 1),
    Result("northfind_latitude", "the north-finding limit against latitude for sensor presets (table, plot)",
           (S("calib lab northfind-latitude --sensors fog_tactical,mpu9250,adis16367 --accuracy-deg 0.5 "
              "--mc {results}/northfind_mc_fog_4pos.json --mc {results}/northfind_mc_mpu9250.json "
              "--png {results}/northfind_latitude.png --json {results}/northfind_latitude.json",
              capture="northfind_latitude.md"),),
           ("northfind_latitude.json", "northfind_latitude.png", "northfind_latitude.md"), 0.5,
           inputs=("northfind_mc_fog_4pos.json", "northfind_mc_mpu9250.json")),
    Result("tilt_static", "the tilt-sensor static test on one simulated device (seed 0)",
           (S("gyrosim tilttable --sensor tilt_001 --seed 0 --out {scratch}/tilt.h5"),
            S("calib tilt {scratch}/tilt.h5 --json {results}/tilt_static.json --png {results}/tilt_static.png",
              capture="tilt_static.md")),
           ("tilt_static.json", "tilt_static.png", "tilt_static.md"), 1),
    Result("tilt_mc", "each tilt-test figure against the drawn device, 50 devices",
           (S("calib lab tilt-mc --sensor tilt_001 --seeds 50 --json {results}/tilt_mc.json", capture="tilt_mc.md"),),
           ("tilt_mc.json", "tilt_mc.md"), 2),
    # ------------------------------------------------------------------ orientation (docs/orientation.md)
    Result("orientation_broad", "VQF, Madgwick, Mahony, Fusion on BROAD beside the published numbers",
           (S("gyrosim orientation-broad --json {results}/orientation_broad.json", capture="orientation_broad.md"),),
           ("orientation_broad.json", "orientation_broad.md"), 3, data=True),
    Result("orientation_campaign", "4 orientation filters × 4 hands × 50 MPU-9250 sessions, raw and calibrated",
           (S("gyrosim campaign --orientation vqf,madgwick,mahony,fusion --hand ideal,steady,typical,shaky --seeds 50 "
              "--sensor mpu9250 --scheduler none --out {scratch}/orientation"),
            S("python benchmarks/collect.py {scratch}/orientation orientation_summary.md orientation_by_bias.md "
              "orientation_vs_severity.png orientation_raw_vs_calibrated.png orientation_summary.csv "
              "--to {results}")),
           ("orientation_summary.md", "orientation_by_bias.md", "orientation_vs_severity.png",
            "orientation_raw_vs_calibrated.png", "orientation_summary.csv"), 15),
    Result("orientation_9axis", "the 9-axis filters on a magnetometer session (10 sessions, typical hand)",
           (S("gyrosim campaign --orientation vqf_9d,madgwick_9d,mahony_9d,fusion_9d --hand typical --seeds 10 "
              "--sensor mpu9250_9axis --scheduler none --out {scratch}/orientation_9axis"),
            S("python benchmarks/collect.py {scratch}/orientation_9axis orientation_summary.md:orientation_9axis.md "
              "--to {results}")),
           ("orientation_9axis.md",), 2),
    Result("orientation_speed", "CPU per orientation-campaign session, by part",
           (S("gyrosim campaign-bench --orientation --sessions 4", capture="orientation_speed.md"),),
           ("orientation_speed.md",), 2),
    # ------------------------------------------------------------------ magnetometer (docs/magnetometer.md)
    Result("mag_compare", "in-motion compass compensation (KF, adaptive KF, particle filter) against calibration",
           (S("calib lab mag-compare --png {results}/mag_heading_allan.png", capture="mag_compare.md"),),
           ("mag_compare.md", "mag_heading_allan.png"), 1),
    Result("mag_measured", "the measured recordings' magnetometers: field spread and heading before and after",
           (S("calib lab mag-measured", capture="mag_measured.md"),), ("mag_measured.md",), 2, data=True),
    Result("mag_bench", "speed of the magnetometer fits", (S("calib lab mag-bench", capture="mag_bench.md"),),
           ("mag_bench.md",), 0.5),
    Result("closeloop_suite_mag", "the magnetometer cases of the closed loop, 20 seeds",
           (S("calib lab closeloop-suite --cases mag --seeds 20", capture="closeloop_suite_mag.md"),),
           ("closeloop_suite_mag.md",), 5),
    Result("magnetometer_closeloop_broad", "the magnetometer loop on BROAD trials 30 and 34",
           (S("python benchmarks/closeloop_mag_broad.py", capture="magnetometer_closeloop_broad.json", fmt="json"),),
           ("magnetometer_closeloop_broad.json",), 3, data=True),
    Result("magnetometer_closeloop_broad_table", "the magnetometer loop on BROAD trials 30 and 34 as a table",
           (S("python benchmarks/closeloop_mag_broad.py --table {results}/magnetometer_closeloop_broad.json",
              capture="magnetometer_closeloop_broad.md", fmt="markdown"),),
           ("magnetometer_closeloop_broad.md",), 0.1, inputs=("magnetometer_closeloop_broad.json",)),
    # ------------------------------------------------------------------ campaigns (docs/campaigns.md)
    Result("campaign_mpu9250", "1000 sessions × 7 hand-blind estimators, MPU-9250 (accelerometer calibrated)",
           (S("gyrosim campaign --hand ideal,steady,typical,shaky --seeds 250 --sensor mpu9250 "
              "--calibrated-accelerometer --method kf,iterated,kf_session_r,kf_adaptive,kf_gated,kf_adaptive_gated,"
              "calib.session.registry:lever_arm_two_pass --out {scratch}/campaign"),
            S("python benchmarks/collect.py {scratch}/campaign summary.csv:campaign_summary.csv "
              "error_vs_severity.png:campaign_error_vs_severity.png --to {results}")),
           ("campaign_summary.csv", "campaign_error_vs_severity.png"), 120),
    Result("campaign_mpu9250_table", "the 1000-session campaign as a table",
           (S("python benchmarks/collect.py --campaign-table {results}/campaign_summary.csv",
              capture="campaign_summary.md", fmt="markdown"),),
           ("campaign_summary.md",), 0.1, inputs=("campaign_summary.csv",)),
    Result("campaign_bench", "campaign scaling: in-process, 1 and 2 Dask workers",
           (S("gyrosim campaign-bench --sessions 12", capture="campaign_bench.md"),), ("campaign_bench.md",), 3,
           note="uses both cores"),
    Result("campaign_speed", "CPU per kf_hand campaign session, stage by stage",
           (S("python benchmarks/campaign_speed.py --sessions 4 --hand typical --method kf_hand "
              "--json {results}/campaign_speed.json", capture="campaign_speed.md"),),
           ("campaign_speed.json", "campaign_speed.md"), 2),
    Result("campaign_kf_hand_1000", "1000 sessions × kf_hand on 2 workers, simulation included: wall time",
           (S("/usr/bin/time -v gyrosim campaign --hand ideal,steady,typical,shaky --seeds 250 --method kf_hand "
              "--calibrated-accelerometer --scheduler local --workers 2 --out {scratch}/camp1000",
              capture="campaign_kf_hand_1000.md"),),
           ("campaign_kf_hand_1000.md",), 30, note="uses both cores for ~12 min"),
    # ------------------------------------------------------------------ closed loop (docs/closeloop.md)
    Result("closeloop_suite", "the closed loop's undeclared-effect suites, 10 seeds",
           (S("calib lab closeloop-suite --seeds 10", capture="closeloop_suite.md"),), ("closeloop_suite.md",), 15),
    Result("closeloop_measured", "the closed loop on every measured recording",
           tuple(S(f"calib closeloop dataset:{d} --out {{scratch}}/{i}", capture="closeloop_measured.md")
                 for i, d in enumerate(("broad/02_undisturbed_slow_rotation_B",
                                        "broad/05_undisturbed_slow_rotation_with_breaks_B",
                                        "broad/07_undisturbed_fast_rotation_B",
                                        "broad/16_undisturbed_fast_translation_B",
                                        "broad/25_disturbed_tapping_B", "broad/30_disturbed_stationary_magnet_C",
                                        "broad/34_disturbed_attached_magnet_3cm", "imu_tk_xsens", "imucal_ferraris",
                                        "xio_fusion", "xio_ximu_thermometer"))),
           ("closeloop_measured.md",), 6, data=True),
    Result("closeloop_bench", "closeloop's time against the Zhou filter on the same recordings",
           (S("calib lab closeloop-bench", capture="closeloop_bench.md"),), ("closeloop_bench.md",), 1, data=True,
           note="calib lab closeloop-bench exits 2 on this code: its baseline calibrate() refuses BROAD 07's "
                "accelerometer"),
    # ------------------------------------------------------------------ noise (docs/noise.md)
    Result("noise_avr", "allan_variance_ros's simulation configuration, 20 seeds × 2 triads × 3 axes",
           (S("python benchmarks/noise_mc.py avr --seeds 20 --out {results}/noise_avr.json"),),
           ("noise_avr.json",), 55),
    Result("noise_selection", "model selection and interval coverage: four true models, 70 seeds × 3 axes",
           (S("python benchmarks/noise_mc.py selection --seeds 70 --out {results}/noise_selection.json"),),
           ("noise_selection.json",), 60),
    Result("noise_tables", "the two noise Monte Carlo campaigns as tables",
           (S("python benchmarks/noise_mc.py avr --table {results}/noise_avr.json", capture="noise_avr.md",
              fmt="markdown"),
            S("python benchmarks/noise_mc.py selection --table {results}/noise_selection.json",
              capture="noise_selection.md", fmt="markdown")),
           ("noise_avr.md", "noise_selection.md"), 0.1, inputs=("noise_avr.json", "noise_selection.json")),
    Result("noise_plan", "calib plan: how long to record an MPU-9250 for ±10 % at 1σ",
           (S("calib plan --sensor mpu9250 --target 0.1 --target-s 1e-4 --target-g 1e-4", capture="noise_plan.md"),),
           ("noise_plan.md",), 0.5),
    Result("noise_speed", "calib noise against calib allan on a 2-hour record",
           (S("python benchmarks/noise_speed.py --repeats 3", capture="noise_speed.md"),), ("noise_speed.md",), 1),
    Result("noise_measured", "calib noise on the still parts of the measured recordings",
           tuple(S(f"calib noise dataset:{d} {span} --triad {tri} --json {{scratch}}/{i}.json",
                   capture="noise_measured.md")
                 for i, (d, span, tri) in enumerate(
                     [(d, span, tri) for d, span in (("imu_tk_xsens", "--longest-still"),
                                                     ("xio_fusion", "--longest-still"),
                                                     ("imucal_ferraris", "--still-segments"),
                                                     ("broad/02_undisturbed_slow_rotation_B", "--still-segments"))
                      for tri in ("gyro", "acc")]))
           + (S("calib noise dataset:broad/05_undisturbed_slow_rotation_with_breaks_B --still-segments --triad gyro "
                "--json {scratch}/broad05.json --png {results}/noise_broad05_gyro.png", capture="noise_measured.md"),),
           ("noise_measured.md", "noise_broad05_gyro.png"), 6, data=True,
           note="the x-io thermometer session is not here: it moves in nearly every 1-s window, and calib noise "
                "refuses it (exit 2: no still stretch of 5 s)"),
    Result("noise_example", "the noise-inflation figure on an independent white + flicker + random-walk record",
           (S("python benchmarks/noise_example.py --csv {scratch}/record.csv"),
            S("calib noise {scratch}/record.csv --gyro-unit deg/s --acc-unit g --json {results}/noise_example.json "
              "--png {results}/noise_example.png"),
            S("python benchmarks/noise_example.py --table {results}/noise_example.json", capture="noise_example.md",
              fmt="markdown")),
           ("noise_example.json", "noise_example.png", "noise_example.md"), 1),
    # ------------------------------------------------------------------ calibration, temperature, simulation
    Result("calibration_reading_a", "Table 7 reading A: efficiency against the Cramér–Rao bound, 50 seeds, ideal hand",
           (S("calib lab montecarlo --sensor zhou2020_sim --hand ideal --seeds 50 "
              "--methods kf,iterated_session_r "
              "--json {results}/calibration_reading_a.json", capture="calibration_reading_a.md"),),
           ("calibration_reading_a.json", "calibration_reading_a.md"), 5),
    Result("calibration_reading_b", "Table 7 reading B (consumer noise): the same",
           (S("calib lab montecarlo --sensor zhou2020_sim_consumer --hand ideal --seeds 50 "
              "--methods kf,iterated_session_r "
              "--json {results}/calibration_reading_b.json", capture="calibration_reading_b.md"),),
           ("calibration_reading_b.json", "calibration_reading_b.md"), 5),
    Result("calibration_mpu9250", "the MPU-9250 with its accelerometer calibrated: what the paper's filter misses",
           (S("calib lab montecarlo --sensor mpu9250 --calibrated-accelerometer --hand ideal --seeds 50 "
              "--methods kf,iterated_session_r --json {results}/calibration_mpu9250.json",
              capture="calibration_mpu9250.md"),),
           ("calibration_mpu9250.json", "calibration_mpu9250.md"), 5),
    Result("attitude_validation", "the demo's attitude validation (free-style rotation, typical hand), two sensors",
           tuple(x for s in ("zhou2020_sim", "zhou2020_sim_consumer")
                 for x in (S(f"calib demo --sensor {s} --out {{scratch}}/{s}"),
                           S(f"python benchmarks/collect.py --section {{scratch}}/{s}/report.md 'Attitude validation'",
                             capture="attitude_validation.md", fmt="markdown"))),
           ("attitude_validation.md",), 2),
    Result("temperature_chamber", "temperature models on held-out chamber cycles, and the rate-table points",
           (S("gyrosim chamber --profile tde_cycles_003 --sensor consumer_thermal --rate 1 --out {scratch}/chamber.h5"),
            S("gyrosim ratetable --profile points_001 --sensor consumer_thermal --out {scratch}/ratetable.h5"),
            S("calib temperature {scratch}/chamber.h5 --ratetable {scratch}/ratetable.h5 "
              "--json {results}/temperature_chamber.json", capture="temperature_chamber.md")),
           ("temperature_chamber.json", "temperature_chamber.md"), 6),
    Result("allan_mc", "what a 2-hour static record tells through the Allan deviation: the MPU-9250 gyro, 12 seeds",
           (S("python benchmarks/allan_mc.py --seeds 12 --json {results}/allan_mc.json", capture="allan_mc.md",
              fmt="markdown"),),
           ("allan_mc.json", "allan_mc.md"), 4),
    Result("hands", "the hand presets and the disturbance each produces over zhou2020",
           (S("gyrosim hands", capture="hands.md"),), ("hands.md",), 0.5),
    Result("bench", "simulation speed against bare mujoco.rollout, and the error model against bare numpy",
           (S("gyrosim bench", capture="bench.md"), S("gyrosim bench sensor", capture="bench.md")),
           ("bench.md",), 2, note="the scene bench needs the second core free"),
    Result("input_checks", "what the input boundary costs calib run",
           (S("python benchmarks/input_checks.py --repeats 5", capture="input_checks.md"),), ("input_checks.md",), 3),
)

BY_NAME = {r.name: r for r in REGISTRY}
BY_OUTPUT = {o: r for r in REGISTRY for o in r.outputs}


# ---------------------------------------------------------------------------------------------- running
def run(result: Result, out_dir: Path = RESULTS, echo=print) -> dict:
    """Run ``result``'s steps, write its files into ``out_dir`` and stamp them; returns the stamp."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env = {**os.environ, "PYTHONPATH": path, "OMP_NUM_THREADS": "1"}
    captures: dict[str, list[tuple[str, str, str]]] = {}
    codes, t0 = [], time.time()
    with tempfile.TemporaryDirectory(prefix=f"result-{result.name}-") as scratch:
        where = _shown(out_dir)
        for step in result.steps:
            shown = step.command.format(results="docs/results", scratch="$SCRATCH")
            argv = [sys.executable if a == "python" else a
                    for a in shlex.split(step.command.format(results=where, scratch=scratch))]
            echo(f"  $ {shown}")
            p = subprocess.run(argv, cwd=ROOT, env=env, text=True,
                               stdout=subprocess.PIPE if step.capture else None)
            codes.append(p.returncode)
            if p.returncode not in (0, 1):
                raise RuntimeError(f"{result.name}: `{shown}` exited {p.returncode}")
            if step.capture:
                captures.setdefault(step.capture, []).append((shown, _scrub(p.stdout, scratch, where), step.fmt))
        for name, parts in captures.items():
            _write_capture(out_dir / name, result, parts)
        for name in result.outputs:   # no machine path in a results file: the scratch folder and the checkout named
            path = out_dir / name
            if path.exists() and path.suffix in (".json", ".md", ".csv"):
                text = path.read_text(encoding="utf-8")
                if _scrub(text, scratch, where) != text:
                    path.write_text(_scrub(text, scratch, where), encoding="utf-8")
    prov = provenance.stamp_for(" && ".join(result.commands()),
                                generator=f"python -m benchmarks.results --only {result.name}",
                                seconds=round(time.time() - t0, 1), exit_codes=codes)
    if result.inputs:
        prov["inputs"] = {f: provenance.short(provenance.read(out_dir / f)) for f in result.inputs}
    for name in result.outputs:
        path = out_dir / name
        if not path.exists():
            raise RuntimeError(f"{result.name}: its steps did not write {name}")
        provenance.stamp(path, prov)
    return prov


def _shown(out_dir: Path) -> str:
    """docs/results as the commands are shown (relative to the checkout, where they run)."""
    try:
        return str(out_dir.resolve().relative_to(ROOT))
    except ValueError:
        return str(out_dir)


def _scrub(text: str, scratch: str, where: str) -> str:
    text = text.replace(scratch, "$SCRATCH").replace(str(Path(scratch).resolve()), "$SCRATCH")
    if Path(where).is_absolute():
        text = text.replace(where, "docs/results")
    return text.replace(str(ROOT) + os.sep, "")


def _write_capture(path: Path, result: Result, parts: list[tuple[str, str, str]]) -> None:
    if parts[0][2] == "json":
        path.write_text(parts[0][1], encoding="utf-8")
        return
    lines = [f"# {result.title[0].upper()}{result.title[1:]}", ""]
    for command, text, fmt in parts:
        lines += [f"`{command}`", ""]
        lines += [text.rstrip(), ""] if fmt == "markdown" else ["```text", text.rstrip(), "```", ""]
    path.write_text("\n".join(lines), encoding="utf-8")


def listing() -> str:
    """One line per result: name, duration, quick or long, where its files stand, what it is."""
    lines = [f"{'result':38s} {'min':>5s}  {'stamped':22s} files / what"]
    for r in REGISTRY:
        states = {provenance.short(provenance.read(RESULTS / o)) if (RESULTS / o).exists() else "missing"
                  for o in r.outputs}
        lines.append(f"{r.name:38s} {r.minutes:5.1f}  {', '.join(sorted(states)):22s} {r.title}"
                     + (" [needs $GYROSIM_DATA]" if r.data else ""))
        lines.append(f"{'':68s} → {', '.join(r.outputs)}")
    return "\n".join(lines)


def _data_present() -> bool:
    from gyrosim.loaders import available_datasets

    return bool(available_datasets())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.results", description=__doc__.splitlines()[0])
    ap.add_argument("--list", action="store_true", help="list every result and exit")
    ap.add_argument("--only", help="comma-separated result names (default: every result)")
    ap.add_argument("--quick", action="store_true", help=f"only the results that take ≤ {QUICK_MINUTES:g} min")
    ap.add_argument("--render", action="store_true", help="only re-render the guides' result snippets")
    ap.add_argument("--dry-run", action="store_true", help="print the commands, run nothing")
    a = ap.parse_args(argv)
    if a.list:
        print(listing())
        return 0
    if a.render:
        for path in snippets.render_all():
            print(f"rendered {path.relative_to(ROOT)}")
        return 0
    names = a.only.split(",") if a.only else [r.name for r in REGISTRY]
    unknown = [n for n in names if n not in BY_NAME]
    if unknown:
        print(f"unknown result(s): {', '.join(unknown)}; `--list` names them", file=sys.stderr)
        return 2
    chosen = [BY_NAME[n] for n in names if not a.quick or BY_NAME[n].quick]
    data = None
    failed = []
    for r in chosen:
        print(f"{r.name} (~{r.minutes:g} min): {r.title}", flush=True)
        if a.dry_run:
            print("\n".join(f"  $ {c}" for c in r.commands()))
            continue
        if r.data and not (data if data is not None else (data := _data_present())):
            print("  skipped: the measured recordings are absent (set GYROSIM_DATA)")
            continue
        try:
            prov = run(r)
        except RuntimeError as exc:
            print(f"  failed: {exc}", file=sys.stderr)
            failed.append(r.name)
            continue
        print(f"  wrote {', '.join(r.outputs)} ({prov['seconds']:.0f} s, {provenance.short(prov)})", flush=True)
    if not a.dry_run:
        for path in snippets.render_all():
            print(f"rendered {path.relative_to(ROOT)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
