#!/usr/bin/env bash
# Renders the benchmark scenes (scenes/bench/*.rib) and prints, per scene and
# thread count, the frame's wall time (best of RUNS runs, default 7,
# `wall_seconds` of --stats), micropolygons per second, and the speed-up of
# all threads over one. Builds first if needed.
#
# The runs with one thread and with all threads alternate: this machine's
# speed drifts by 10-15% over minutes with the load of the host it shares,
# and timing one configuration after the other would compare two different
# machines.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x build/bin/umbra ] || scripts/build.sh
runs=${RUNS:-7}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
threads_all=$(nproc)
printf "%-24s %8s %10s %13s %9s\n" scene threads "wall (s)" "Mmicropoly/s" speed-up
for rib in scenes/bench/*.rib; do
  declare -A best=() mps=()
  for run in $(seq "$runs"); do
    for threads in 1 "$threads_all"; do
      (cd "$out" && "$OLDPWD/build/bin/umbra" render "$OLDPWD/$rib" --threads "$threads" --quiet --stats stats.json)
      read -r wall mp < <(python3 -c "
import json
f = json.load(open('$out/stats.json'))['frames'][0]
print(f['wall_seconds'], f['passes'][-1]['counts']['micropolygons'])")
      if [ -z "${best[$threads]:-}" ] || python3 -c "import sys;sys.exit(0 if $wall < ${best[$threads]} else 1)"; then
        best[$threads]=$wall
        mps[$threads]=$mp
      fi
    done
  done
  for threads in 1 "$threads_all"; do
    python3 -c "
b, one, mp = ${best[$threads]}, ${best[1]}, ${mps[$threads]}
print('%-24s %8s %10.3f %13.2f %8.2fx' % ('$(basename "$rib")', '$threads', b, mp / b / 1e6, one / b))"
  done
  unset best mps
done
