#!/usr/bin/env bash
# Set up .venv (if needed) and track the bundled sample video with a counting line;
# outputs go to runs/sample/ (tracks.csv, summary.json, crossings.csv, annotated.mp4, tracks.rrd).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup_env.sh
.venv/bin/vtrack track videos/sample.mp4 --out runs/sample --save-video \
  --rerun runs/sample/tracks.rrd --count-line 320,0,320,360 "$@"
.venv/bin/vtrack eval videos/sample_gt.csv runs/sample/tracks.csv
