#!/usr/bin/env bash
# The cost of a shadow lookup by depth filter (issue 5's target: a `second`
# lookup with virtual samples at most 1.5x a plain PCF lookup over a
# frame). Renders scenes/quality/sphere.rib (open floor) and sphere_slab.rib
# (solids only) at 640x480 with their 512² automatic maps, once with
# depthfilter "min" and once with "second", on one thread, and prints
# lookup_seconds / points of --stats: best and median of RUNS (default 11)
# renders of each, the two filters alternating (the host's speed drifts).
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x build/bin/umbra ] || scripts/build.sh
runs=${RUNS:-11}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for scene in sphere sphere_slab; do
  for filter in min second; do
    sed -e 's/^Format .*/Format 640 480 1/' \
        -e "s/\"depthfilter\" \[\"second\"\]/\"depthfilter\" [\"$filter\"]/" \
        -e "s#^Display .*#Display \"$out/$filter.tif\" \"file\" \"rgba\"#" \
        -e "s#\"shaders:&\"#\"$PWD/scenes/quality/shaders:\&\"#" \
        "scenes/quality/$scene.rib" > "$out/$filter.rib"
  done
  for run in $(seq "$runs"); do
    for filter in min second; do
      build/bin/umbra render "$out/$filter.rib" --threads 1 --quiet --stats "$out/$filter.json"
      python3 -c "
import json
s = json.load(open('$out/$filter.json'))['frames'][0]['shadow']
print('$filter', s['lookup_seconds'] / s['points'] * 1e9, s['points'], s['virtual_sample_points'], s['stored_plane_lit'])"
    done
  done | python3 -c "
import statistics, sys
ns, counts = {}, {}
for line in sys.stdin:
    f, v, *c = line.split()
    ns.setdefault(f, []).append(float(v))
    counts[f] = c
for f in ('min', 'second'):
    print(f'$scene {f:6s} best {min(ns[f]):6.1f} ns  median {statistics.median(ns[f]):6.1f} ns'
          f'  (points {counts[f][0]}, virtual-sample points {counts[f][1]}, lit from stored planes {counts[f][2]})')
print(f'$scene ratio  best {min(ns[\"second\"]) / min(ns[\"min\"]):.2f}x'
      f'  median {statistics.median(ns[\"second\"]) / statistics.median(ns[\"min\"]):.2f}x')"
done
