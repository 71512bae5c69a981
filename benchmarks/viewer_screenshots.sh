#!/usr/bin/env bash
# The screenshots of docs/viewer.md: every recording we write, made fresh, opened in rerun's web viewer
# in headless Chromium (benchmarks/render_rrd.py), nothing clicked.  Needs `apt-get install chromium` and
# `pip install playwright` (not project dependencies) and the measured data (GYROSIM_DATA or ../shared/data).
#   bash benchmarks/viewer_screenshots.sh [WORK_DIR] [PNG_DIR]     # defaults: a fresh temporary folder, docs/viewer
set -euo pipefail
W=${1:-$(mktemp -d)}
P=${2:-docs/viewer}
WAIT=${WAIT:-50}          # seconds the viewer gets to load a file (software rendering on a loaded 2-core machine)
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1
mkdir -p "$W" "$P"
rm -rf "$W/demo" "$W/closeloop" "$W/campaign"
calib demo --out "$W/demo"
calib run dataset:broad/05_undisturbed_slow_rotation_with_breaks_B --rrd "$W/calib_run_measured.rrd" || true  # exit 1: inconsistent, still written
calib closeloop dataset:broad/07_undisturbed_fast_rotation_B --out "$W/closeloop"
gyrosim chamber --profile tde_cycles_003 --sensor consumer_thermal --seed 1 --out "$W/chamber.h5"
calib temperature "$W/chamber.h5" --rrd "$W/temperature.rrd"
calib mag dataset:broad/30_disturbed_stationary_magnet_C --rrd "$W/mag.rrd"
gyrosim orientation-view --hand typical --seed 1 --estimators vqf,madgwick,mahony,fusion --rrd "$W/orientation.rrd"
gyrosim campaign --hand ideal,steady,typical,shaky --severity 1,2 --seeds 3 --method kf,kf_adaptive,smoother \
    --scheduler none --out "$W/campaign"
python benchmarks/render_rrd.py --wait "$WAIT" \
    "$W/demo/session.rrd" "$P/calib_demo.png" \
    "$W/calib_run_measured.rrd" "$P/calib_run_measured.png" \
    "$W/closeloop/closeloop.rrd" "$P/closeloop.png" \
    "$W/temperature.rrd" "$P/temperature.png" \
    "$W/mag.rrd" "$P/mag.png" \
    "$W/orientation.rrd" "$P/orientation.png" \
    "$W/campaign/summary.rrd" "$P/campaign.png"
