#!/usr/bin/env python3
"""The cost of motion blur in the camera pass (issue 18): renders
scenes/bench/pixie_motion.rib and pixie_motion_still.rib (the same frame with
the shutter closed) alternately, RUNS times each, and prints the medians of
wall and CPU seconds and their ratio. Run it under the build lock on a
shared machine:

    flock /tmp/umbra-build.lock python3 scripts/motion_cost.py [UMBRA] [--runs N] [--threads T]
"""
import argparse
import os
import shutil
import statistics
import subprocess
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('umbra', nargs='?', default=os.path.join(ROOT, 'build', 'bin', 'umbra'))
    ap.add_argument('--runs', type=int, default=5)
    ap.add_argument('--threads', type=int, default=2)
    args = ap.parse_args()
    umbra = os.path.abspath(args.umbra)
    ribs = ['pixie_motion.rib', 'pixie_motion_still.rib']
    work = tempfile.mkdtemp(prefix='umbra-motion-')
    try:
        for rib in ribs:
            shutil.copy(os.path.join(ROOT, 'scenes', 'bench', rib), work)
        wall = {r: [] for r in ribs}
        cpu = {r: [] for r in ribs}
        for _ in range(args.runs):
            for rib in ribs:
                t0 = time.perf_counter()
                proc = subprocess.Popen([umbra, 'render', rib, '--threads', str(args.threads), '--quiet'], cwd=work)
                _, status, usage = os.wait4(proc.pid, 0)
                if os.waitstatus_to_exitcode(status) != 0:
                    raise SystemExit('%s failed on %s' % (umbra, rib))
                wall[rib].append(time.perf_counter() - t0)
                cpu[rib].append(usage.ru_utime + usage.ru_stime)
        for name, d in (('wall', wall), ('cpu', cpu)):
            m, s = statistics.median(d[ribs[0]]), statistics.median(d[ribs[1]])
            print('%-4s  blurred %.3f s  still %.3f s  cost %.2fx   (runs %s / %s)' %
                  (name, m, s, m / s, ' '.join('%.3f' % x for x in d[ribs[0]]),
                   ' '.join('%.3f' % x for x in d[ribs[1]])))
    finally:
        shutil.rmtree(work)


if __name__ == '__main__':
    main()
