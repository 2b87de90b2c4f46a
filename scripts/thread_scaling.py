#!/usr/bin/env python3
"""How well umbra uses two threads, against what this host gives two
processes that share nothing.

The two virtual CPUs of these hosts change speed from minute to minute and
do not always run at the same speed (docs/performance.md, "Two threads"), so
a speed-up measured alone says as much about the host as about the code.
Each round therefore runs, back to back:

  alone   the RIB at --threads 1;
  pair    two copies of that run at once, in separate folders: they share
          no memory, lock or cache line, so 2 x alone / pair is the most any
          two-thread program could gain on the host at that moment (its
          ceiling);
  two     the RIB at --threads N (N = 2 unless told).

and prints the speed-up (alone / two), the ceiling, and their ratio, the
parallel efficiency that is the code's own. Medians over the rounds.

    scripts/thread_scaling.py [--runs 8] [--threads 2] [scene.rib]

The default scene is scenes/bench/production/production.rib (issue 21's
frame, all its passes and MakeShadows), rendered in scratch copies of its
folder."""
import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
UMBRA = os.path.join(ROOT, 'build', 'bin', 'umbra')


def start(umbra, rib, work, threads):
    env = dict(os.environ, SOURCE_DATE_EPOCH='0')
    return subprocess.Popen([umbra, 'render', '--quiet', '--threads', str(threads), os.path.basename(rib)],
                            cwd=work, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def finish(proc):
    _, status, usage = os.wait4(proc.pid, 0)
    err = proc.stderr.read().decode(errors='replace')
    proc.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit('umbra failed:\n' + err[-2000:])
    return usage.ru_utime + usage.ru_stime


def timed(umbra, rib, works, threads):
    """Wall seconds until every copy has finished, and each copy's CPU seconds."""
    t0 = time.perf_counter()
    procs = [start(umbra, rib, w, threads) for w in works]
    cpu = [finish(p) for p in procs]
    return time.perf_counter() - t0, cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('rib', nargs='?', default=os.path.join(ROOT, 'scenes', 'bench', 'production', 'production.rib'))
    ap.add_argument('--runs', type=int, default=8)
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--umbra', default=None, help='the umbra binary (default: build/bin/umbra)')
    args = ap.parse_args()
    umbra = os.path.abspath(args.umbra or UMBRA)
    src = os.path.dirname(os.path.abspath(args.rib))
    works = []
    try:
        for _ in range(args.threads):
            w = tempfile.mkdtemp(prefix='umbra-scaling-')
            for f in os.listdir(src):
                if os.path.isfile(os.path.join(src, f)):
                    shutil.copy(os.path.join(src, f), w)
            works.append(w)
        timed(umbra, args.rib, works[:1], 1)  # warm the page cache and the shaders
        rows = []
        print('%5s %9s %9s %9s %9s %9s %10s %6s' % ('round', 'alone (s)', 'pair (s)', 'two (s)', 'speed-up',
                                                    'ceiling', 'efficiency', 'load'))
        for r in range(args.runs):
            alone, _ = timed(umbra, args.rib, works[:1], 1)
            pair, _ = timed(umbra, args.rib, works, 1)
            two, _ = timed(umbra, args.rib, works[:1], args.threads)
            speedup, ceiling = alone / two, args.threads * alone / pair
            rows.append((alone, pair, two, speedup, ceiling, speedup / ceiling))
            print('%5d %9.3f %9.3f %9.3f %8.2fx %8.2fx %10.2f %6.2f' % (r + 1, *rows[-1], os.getloadavg()[0]))
            sys.stdout.flush()
        med = [statistics.median(c) for c in zip(*rows)]
        print('%5s %9.3f %9.3f %9.3f %8.2fx %8.2fx %10.2f' % ('median', *med))
        best = min(r[0] for r in rows) / min(r[2] for r in rows)
        print('best alone / best two: %.2fx' % best)
    finally:
        for w in works:
            shutil.rmtree(w, ignore_errors=True)


if __name__ == '__main__':
    main()
