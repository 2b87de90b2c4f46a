#!/usr/bin/env bash
# The benchmark scenes (scenes/bench), umbra against Pixie when the peers are
# there: see scripts/bench.py for what is measured. Builds first if needed.
set -euo pipefail
cd "$(dirname "$0")/.."
exec python3 scripts/bench.py "$@"
