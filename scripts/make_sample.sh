#!/usr/bin/env bash
# Regenerate the bundled demo clip videos/sample.avi and its ground truth videos/sample_gt.csv
# with `vtrack synth` (480x270, 200 frames at 25 fps, MJPG quality 10: under 3 MB).
set -euo pipefail
cd "$(dirname "$0")/.."
PY="${PYTHON:-.venv/bin/python}"
tmp="$(mktemp -d videos/.sample.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
"$PY" -m vtrack synth "$tmp" --frames 200 --vehicles 14 --width 480 --height 270 --fps 25 \
    --seed 1 --quality 10
mv "$tmp/video.avi" videos/sample.avi
mv "$tmp/gt.csv" videos/sample_gt.csv
