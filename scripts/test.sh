#!/usr/bin/env bash
# Set up .venv (if needed) and run the test suite (two worker processes).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup_env.sh
exec .venv/bin/python -m pytest -n 2 "$@"
