#!/usr/bin/env bash
# Renders the benchmark scenes (scenes/bench/*.rib) and prints wall time and
# micropolygons per second for 1 and all threads. Builds first if needed.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x build/bin/umbra ] || scripts/build.sh
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
printf "%-28s %8s %10s %12s\n" scene threads "wall (s)" "Mmicropoly/s"
for rib in scenes/bench/*.rib; do
  for threads in 1 "$(nproc)"; do
    best=""
    for run in 1 2 3; do
      (cd "$out" && "$OLDPWD/build/bin/umbra" render "$OLDPWD/$rib" --threads "$threads" --quiet --stats stats.json)
      wall=$(python3 -c "import json;f=json.load(open('$out/stats.json'))['frames'][0];print(f['wall_seconds'])")
      if [ -z "$best" ] || python3 -c "import sys;sys.exit(0 if $wall < $best else 1)"; then best=$wall; fi
    done
    mps=$(python3 -c "import json;f=json.load(open('$out/stats.json'))['frames'][0];print(round(f['passes'][0]['counts']['micropolygons']/$best/1e6,2))")
    printf "%-28s %8s %10.3f %12s\n" "$(basename "$rib")" "$threads" "$best" "$mps"
  done
done
