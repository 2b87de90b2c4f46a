#!/usr/bin/env python3
"""Where a frame's time goes, by pipeline stage: runs `perf record` on an
umbra command and sums the samples of each function into the stage it
belongs to (by its namespace and name).

    python3 scripts/profile_stages.py [--threads N] scene.rib

Needs perf (Debian's linux-perf) with cycle sampling available. Stages:
parse (RIB and scene building), bound/split/dice (geometry and dicing),
shading VM (surface, displacement and light shaders, their built-ins),
shadow lookups (shadow() and the depth-map cache), sampling (micropolygons
against pixel samples), filtering (samples to pixels), output (image and
map files), scheduler (buckets, grids' lifetimes), memory (malloc/free),
other. Printed as a table of per cent of samples.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile
from collections import defaultdict

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# First match wins: (stage, pattern on "dso symbol").
STAGES = [
    ('shadow lookups', r'ShadowMap|shadow_lookup|PointRegions|TileCache|tile_cache|shading::.*\bshadow\b|ShadowBatch|depth_image'),
    ('filtering', r'SampleBuffer::resolve|splat|PixelFilter|inverseWeightSum'),
    ('sampling', r'SampleBuffer::|hider::.*Tri|takeNearest|samplePosition|SamplePattern'),
    ('shading VM', r'umbra::shading::|libm\.so|noise|Exec::'),
    ('scheduler', r'BucketScheduler|hider::Frame|hider::.*Node'),
    ('bound/split/dice', r'umbra::geometry::|umbra::dice::|SurfacePipeline::(plan|rasterBound|shade)|transformBound|libosd'),
    ('parse', r'umbra::ri::|umbra::scene::|Lexer|Parser'),
    ('output', r'film::|TIFF|tiff|Exr|exr|png|deflate|libz'),
    ('memory', r'malloc|free|_int_|unlink_chunk|memset|memcpy|memmove|operator new|operator delete'),
]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('rib')
    ap.add_argument('--threads', type=int, default=os.cpu_count())
    ap.add_argument('--umbra', default=os.path.join(ROOT, 'build', 'bin', 'umbra'))
    args = ap.parse_args()
    rib = os.path.abspath(args.rib)
    with tempfile.TemporaryDirectory() as tmp:
        data = os.path.join(tmp, 'perf.data')
        subprocess.run(['perf', 'record', '-q', '-F', '999', '-o', data, args.umbra, 'render', rib, '--quiet',
                        '--threads', str(args.threads)], cwd=os.path.dirname(rib), check=True,
                       stdout=subprocess.DEVNULL)
        report = subprocess.run(['perf', 'report', '-i', data, '--no-children', '--sort', 'dso,symbol', '--stdio',
                                 '-F', 'overhead,dso,symbol'], capture_output=True, text=True, check=True).stdout
    totals = defaultdict(float)
    top = defaultdict(list)
    for line in report.splitlines():
        m = re.match(r'\s*([0-9.]+)%\s+(\S+)\s+\[.\]\s+(.*)', line)
        if not m:
            continue
        pct, dso, sym = float(m.group(1)), m.group(2), re.sub(r'(\s+-)+\s*$', '', re.sub(r'\s+', ' ', m.group(3))).strip()
        key = dso + ' ' + sym
        stage = next((name for name, pat in STAGES if re.search(pat, key)), 'other')
        totals[stage] += pct
        top[stage].append((pct, sym[:60]))
    print('| stage | % of samples | largest functions |')
    print('|---|---:|---|')
    for stage, pct in sorted(totals.items(), key=lambda kv: -kv[1]):
        names = ', '.join('%s %.1f' % (s, p) for p, s in sorted(top[stage], reverse=True)[:3])
        print('| %s | %.1f | %s |' % (stage, pct, names))


if __name__ == '__main__':
    sys.exit(main())
