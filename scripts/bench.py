#!/usr/bin/env python3
"""Renders the benchmark scenes and prints, per scene and thread count, the
wall time of the whole command (best of RUNS runs: every frame of the RIB,
depth-map frames and MakeShadow included, as a user waits for it),
micropolygons per second of the last frame (from --stats), the speed-up of all threads over one, and umbra's peak memory.
When the peer renderers are beside the project (../shared/peers, or
$UMBRA_PEERS), Pixie 2.2.6 renders the same RIB in the same runs
(alternating, since this machine's speed drifts with its host's load) and
the ratio umbra/Pixie is printed; without them, umbra's figures alone.

Scenes: scenes/bench/*.rib, and scenes/bench/<name>/<name>.rib for scenes
that come with their own shaders and archives (rendered in a scratch copy
of their folder, where Pixie's compiled shaders are made too).

    scripts/bench.sh [--runs N] [--scenes a,b] [--no-peers]
"""
import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile

from timed_run import run

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
UMBRA = os.path.join(ROOT, 'build', 'bin', 'umbra')
PEERS = os.environ.get('UMBRA_PEERS', os.path.join(ROOT, '..', 'shared', 'peers'))


def scenes():
    found = sorted(glob.glob(os.path.join(ROOT, 'scenes', 'bench', '*.rib')))
    for d in sorted(glob.glob(os.path.join(ROOT, 'scenes', 'bench', '*', ''))):
        name = os.path.basename(os.path.dirname(d))
        rib = os.path.join(d, name + '.rib')
        if os.path.exists(rib):
            found.append(rib)
    return found


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--runs', type=int, default=int(os.environ.get('RUNS', 7)))
    ap.add_argument('--scenes', help='comma-separated scene names (default: all)')
    ap.add_argument('--no-peers', action='store_true', help='umbra alone even when the peers are there')
    args = ap.parse_args()
    if not os.access(UMBRA, os.X_OK):
        subprocess.run([os.path.join(ROOT, 'scripts', 'build.sh')], check=True)
    pixie = os.path.join(PEERS, 'bin', 'pixie-rndr')
    peers_here = not args.no_peers and os.access(pixie, os.X_OK)
    if not peers_here:
        print('(no peer renderers found: umbra\'s figures alone)')
    threads_all = os.cpu_count()
    wanted = set(args.scenes.split(',')) if args.scenes else None
    print('%-16s %7s %9s %13s %9s %9s %10s %8s %9s' % ('scene', 'threads', 'wall (s)', 'Mmicropoly/s', 'speed-up',
                                                       'peak MiB', 'Pixie (s)', 'umbra/Pixie', 'Pixie MiB'))
    for rib in scenes():
        name = os.path.splitext(os.path.basename(rib))[0]
        if wanted and name not in wanted:
            continue
        work = tempfile.mkdtemp(prefix='umbra-bench-')
        try:
            src = os.path.dirname(rib)
            if os.path.basename(src) == name:  # a scene with its own folder
                for f in os.listdir(src):
                    shutil.copy(os.path.join(src, f), work)
            else:
                shutil.copy(rib, work)
            # Per scene: one Pixie cannot render (umbra's automatic maps)
            # leaves the others' comparisons in place.
            use_pixie = peers_here
            if use_pixie:
                sls = [f for f in os.listdir(work) if f.endswith('.sl')]
                if sls and run([os.path.join(PEERS, 'bin', 'pixie-sdrc')] + sls, work, peer=True) is None:
                    use_pixie = False
            best, mps, rss = {}, {}, {}
            best_pixie = pixie_rss = None
            for _ in range(args.runs):
                for threads in sorted({1, threads_all}):
                    wall, peak = run([UMBRA, 'render', os.path.basename(rib), '--threads', str(threads), '--quiet',
                                   '--stats', 'stats.json'], work)
                    with open(os.path.join(work, 'stats.json')) as f:
                        frames = json.load(f)['frames']
                    mp = frames[-1]['passes'][-1]['counts']['micropolygons']
                    if wall < best.get(threads, 1e30):
                        best[threads], mps[threads], rss[threads] = wall, mp / frames[-1]['wall_seconds'], peak
                if use_pixie:
                    ran = run([pixie, '-t:%d' % threads_all, os.path.basename(rib)], work, peer=True)
                    if ran is None:
                        use_pixie = False
                    else:
                        best_pixie = ran[0] if best_pixie is None else min(best_pixie, ran[0])
                        pixie_rss = ran[1] if pixie_rss is None else max(pixie_rss, ran[1])
            for threads in sorted(best):
                line = '%-16s %7d %9.3f %13.2f %8.2fx %9.0f' % (name, threads, best[threads], mps[threads] / 1e6,
                                                              best[1] / best[threads], rss[threads])
                if use_pixie and best_pixie is not None and threads == threads_all:
                    line += ' %10.3f %8.2f %9.0f' % (best_pixie, best[threads] / best_pixie, pixie_rss)
                print(line)
            sys.stdout.flush()
        finally:
            shutil.rmtree(work)


if __name__ == '__main__':
    main()
