"""One timed child process for the benchmark scripts (bench.py,
bench_geometry.py): its wall time and peak RSS, and what to do when it
fails."""
import os
import subprocess
import sys
import time


def run(cmd, cwd, peer=False):
    """(wall seconds, peak RSS MiB) of one command, which must succeed; a
    peer renderer's failure (a broken peer install) is printed and gives
    None, so the caller goes on with umbra's figures alone."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors='replace')
    proc.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        if peer:
            print('(%s failed, so it is left out of this scene: %s)' % (os.path.basename(cmd[0]), err.strip()[-300:]))
            return None
        sys.exit('%s failed (%d):\n%s' % (' '.join(cmd), code, err[-2000:]))
    return wall, usage.ru_maxrss / 1024.0
