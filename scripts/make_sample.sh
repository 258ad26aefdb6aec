#!/usr/bin/env bash
# Regenerate the bundled demo clip videos/sample.mp4 and its ground truth videos/sample_gt.csv:
# `vtrack synth` (640x360, 250 frames at 25 fps, seed 0) re-encoded from MJPG to MPEG-4 Part 2
# (mp4v) so the clip stays about 3.5 MB.
set -euo pipefail
cd "$(dirname "$0")/.."
PY="${PYTHON:-.venv/bin/python}"
tmp="$(mktemp -d videos/.sample.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
"$PY" -m vtrack synth "$tmp" --frames 250 --width 640 --height 360 --fps 25 --seed 0 --quality 95
"$PY" - "$tmp/video.avi" "$tmp/sample.mp4" <<'PY'
import sys
import cv2
src, dst = sys.argv[1:]
cap = cv2.VideoCapture(src)
out = cv2.VideoWriter(dst, cv2.VideoWriter_fourcc(*"mp4v"), cap.get(cv2.CAP_PROP_FPS),
                      (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))))
while True:
    ok, frame = cap.read()
    if not ok:
        break
    out.write(frame)
out.release()
PY
mv "$tmp/sample.mp4" videos/sample.mp4
mv "$tmp/gt.csv" videos/sample_gt.csv
