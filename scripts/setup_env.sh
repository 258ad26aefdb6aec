#!/usr/bin/env bash
# Create (or reuse) the project's environment in .venv/ with every optional extra.
# Needs only python3 (>= 3.11). Re-running is cheap: it reinstalls only when pyproject.toml
# changed since the last successful install.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
stamp=.venv/.vtrack-installed
want=$(sha256sum pyproject.toml | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ] || ! .venv/bin/python -c "import vtrack, trackeval, trackers" >/dev/null 2>&1; then
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -e ".[all,test]"
  # trackeval 1.3.0 hard-depends on opencv-python (clashes with the headless build) and
  # pycocotools; its MOTChallenge path needs neither, so it is installed without them.
  .venv/bin/python -m pip install --quiet --no-deps "trackeval==1.3.0"
  # The scene suite's peers (SORT, ByteTrack): same opencv-python clash, same remedy; their
  # other dependencies are the `peer` extra.
  .venv/bin/python -m pip install --quiet --no-deps "trackers==2.6.1" "supervision==0.31.2"
  echo "$want" > "$stamp"
fi
# The set-up page's browser test (tests/setup/test_setup_page.py) drives Debian's Chromium
# and its driver. As root with apt-get, install them once when missing (quietly; the marker
# stops a retry on every run if that fails); otherwise the test skips and says why.
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 \
    && ! { command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; } \
    && [ ! -f .venv/.vtrack-chromium-tried ]; then
  touch .venv/.vtrack-chromium-tried
  if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
        chromium chromium-driver; } >/dev/null 2>&1; then
    echo "setup_env: could not install chromium chromium-driver (the browser test will skip)" >&2
  fi
fi
