#!/usr/bin/env bash
# One command from a bare Debian 12 machine to a rendered image: installs
# what is missing, builds in Release, renders scenes/showcase.rib and prints
# the statistics summary.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh -DUMBRA_TESTS=OFF -DUMBRA_BENCHMARKS=OFF
mkdir -p out
(cd scenes && ../build/bin/umbra render showcase.rib --stats ../out/showcase-stats.json)
echo "umbra: wrote scenes/showcase.tif (statistics in out/showcase-stats.json)"
