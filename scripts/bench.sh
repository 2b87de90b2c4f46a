#!/usr/bin/env bash
# Renders the benchmark scenes (scenes/bench/*.rib) and prints, per scene and
# thread count, the frame's wall time (best of 5 runs, `wall_seconds` of
# --stats), micropolygons per second, and the speed-up of all threads over
# one. Builds first if needed.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x build/bin/umbra ] || scripts/build.sh
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
threads_all=$(nproc)
printf "%-24s %8s %10s %13s %9s\n" scene threads "wall (s)" "Mmicropoly/s" speed-up
for rib in scenes/bench/*.rib; do
  one=""
  for threads in 1 "$threads_all"; do
    best=""
    for run in 1 2 3 4 5; do
      (cd "$out" && "$OLDPWD/build/bin/umbra" render "$OLDPWD/$rib" --threads "$threads" --quiet --stats stats.json)
      wall=$(python3 -c "import json;f=json.load(open('$out/stats.json'))['frames'][0];print(f['wall_seconds'])")
      if [ -z "$best" ] || python3 -c "import sys;sys.exit(0 if $wall < $best else 1)"; then best=$wall; fi
    done
    [ -z "$one" ] && one=$best
    mps=$(python3 -c "import json;f=json.load(open('$out/stats.json'))['frames'][0];print(round(f['passes'][-1]['counts']['micropolygons']/$best/1e6,2))")
    speedup=$(python3 -c "print(f'{$one/$best:.2f}x')")
    printf "%-24s %8s %10.3f %13s %9s\n" "$(basename "$rib")" "$threads" "$best" "$mps" "$speedup"
  done
done
