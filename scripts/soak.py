#!/usr/bin/env python3
"""Soak test: renders many random *valid* scenes with a sanitizer build of
umbra under time and memory limits, and counts what goes wrong.

Each scene (made from its seed, so any failure can be made again) holds
random primitives of every family, random attributes, shaders from
shaders_dsl/, lights with automatic depth-map shadows, and random options
within docs/rib.md's limits; some first render a small picture and turn it
into a texture (MakeTexture) that their shaders look up. A scene fails when
umbra crashes (a signal, or an AddressSanitizer/UndefinedBehaviorSanitizer
report), hangs (the time limit), leaks (LeakSanitizer), runs out of memory,
or reports an error (the scenes are valid, so any error is a bug). Warnings
are counted, not failures. Peak memory is printed per scene.

    scripts/soak.py --umbra build-asan/bin/umbra --count 1000
    scripts/soak.py --umbra build-asan/bin/umbra --seed 417 --count 1 --keep

Not part of the default suite (docs/performance.md gives the last result).
"""
import argparse
import math
import os
import random
import resource
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SURFACES = ["matte", "plastic", "metal", "shinymetal", "paintedplastic", "constant", "defaultsurface"]
FILTERS = ["box", "triangle", "gaussian", "catmull-rom", "sinc", "mitchell", "separable-catmull-rom",
           "blackman-harris", "disk", "bessel", "lanczos"]
DEPTH_FILTERS = ["min", "second", "midpoint", "dual"]


def f(x):
    return f"{x:.4g}"


def floats(r, n, lo, hi):
    return " ".join(f(r.uniform(lo, hi)) for _ in range(n))


class Scene:
    def __init__(self, seed):
        self.r = random.Random(seed)
        self.lines = []
        self.texture = self.r.random() < 0.3

    def w(self, s):
        self.lines.append(s)

    # Primitives, each placed around the origin within about one unit.
    def quadric(self):
        r = self.r
        kind = r.choice(["Sphere", "Cylinder", "Cone", "Disk", "Paraboloid", "Hyperboloid", "Torus"])
        tm = f(r.uniform(30, 360))
        rad = f(r.uniform(0.2, 1))
        if kind == "Sphere":
            self.w(f"Sphere {rad} -{rad} {rad} {tm}")
        elif kind == "Cylinder":
            self.w(f"Cylinder {rad} -0.5 0.5 {tm}")
        elif kind == "Cone":
            self.w(f"Cone 1 {rad} {tm}")
        elif kind == "Disk":
            self.w(f"Disk {f(r.uniform(-0.5, 0.5))} {rad} {tm}")
        elif kind == "Paraboloid":
            self.w(f"Paraboloid {rad} 0 1 {tm}")
        elif kind == "Hyperboloid":
            self.w(f"Hyperboloid {floats(r, 3, -1, 1)} {floats(r, 3, -1, 1)} {tm}")
        else:
            self.w(f"Torus {f(r.uniform(0.5, 1))} {f(r.uniform(0.1, 0.4))} 0 360 {tm}")

    def polygon(self):
        r = self.r
        kind = r.choice(["Polygon", "Polygons", "GeneralPolygon", "PointsPolygons", "PointsGeneralPolygons"])
        if kind in ("Polygon", "Polygons"):
            for _ in range(1 if kind == "Polygon" else r.randint(2, 30)):
                n = r.randint(3, 7)
                pts = []
                for k in range(n):
                    a = 2 * math.pi * k / n
                    rr = r.uniform(0.3, 1)
                    pts += [math.cos(a) * rr, math.sin(a) * rr, r.uniform(-0.1, 0.1)]
                extra = ' "Cs" [' + floats(r, 3 * n, 0, 1) + "]" if r.random() < 0.3 else ""
                self.w('Polygon "P" [' + " ".join(f(v) for v in pts) + "]" + extra)
        elif kind == "GeneralPolygon":
            self.w('GeneralPolygon [4 3] "P" [-1 -1 0 1 -1 0 1 1 0 -1 1 0 -0.3 -0.3 0 0.3 -0.3 0 0 0.3 0]')
        elif kind == "PointsPolygons":
            nx = r.randint(1, 6)
            pts, nverts, verts = [], [], []
            for j in range(nx + 1):
                for i in range(nx + 1):
                    pts += [i / nx * 2 - 1, j / nx * 2 - 1, r.uniform(-0.2, 0.2)]
            for j in range(nx):
                for i in range(nx):
                    a = j * (nx + 1) + i
                    nverts.append(4)
                    verts += [a, a + 1, a + nx + 2, a + nx + 1]
            st = ' "st" [' + floats(r, 2 * len(pts) // 3, 0, 1) + "]" if r.random() < 0.5 else ""
            self.w(f"PointsPolygons [{' '.join(map(str, nverts))}] [{' '.join(map(str, verts))}] "
                   f"\"P\" [{' '.join(f(v) for v in pts)}]{st}")
        else:
            self.w('PointsGeneralPolygons [2 1] [4 3 3] [0 1 2 3 4 5 6 0 1 7] '
                   '"P" [-1 -1 0 1 -1 0 1 1 0 -1 1 0 -0.2 -0.2 0 0.2 -0.2 0 0 0.2 0 0 -1.5 0.2]')

    def patch(self):
        r = self.r
        kind = r.choice(["bilinear", "bicubic", "mesh", "nupatch"])
        if kind == "bilinear":
            self.w('Patch "bilinear" "P" [-1 -1 ' + f(r.uniform(-1, 1)) + " 1 -1 0 -1 1 0 1 1 " +
                   f(r.uniform(-1, 1)) + "]")
        elif kind == "bicubic":
            self.w("Basis \"" + r.choice(["bezier", "b-spline", "catmull-rom", "hermite", "power"]) + "\" " +
                   ("3" if r.random() < 0.5 else "1") + " \"bezier\" 3")
            pts = []
            for j in range(4):
                for i in range(4):
                    pts += [i / 1.5 - 1, j / 1.5 - 1, r.uniform(-0.5, 0.5)]
            self.w('Patch "bicubic" "P" [' + " ".join(f(v) for v in pts) + "]")
        elif kind == "mesh":
            nu, nv = r.randint(2, 5), r.randint(2, 5)
            pts = []
            for j in range(nv):
                for i in range(nu):
                    pts += [i / (nu - 1) * 2 - 1, j / (nv - 1) * 2 - 1, r.uniform(-0.3, 0.3)]
            wrap = r.choice(["nonperiodic", "periodic"])
            self.w(f'PatchMesh "bilinear" {nu} "{wrap}" {nv} "nonperiodic" "P" [' + " ".join(f(v) for v in pts) + "]")
        else:
            pts = []
            for j in range(4):
                for i in range(4):
                    pts += [i / 1.5 - 1, j / 1.5 - 1, r.uniform(-0.5, 0.5), 1]
            if r.random() < 0.4:
                self.w("TrimCurve [1] [3] [0 0 0 1 1 1] [0] [1] [3] [0.2 0.8 0.5] [0.2 0.2 0.8] [1 1 1]")
            self.w('NuPatch 4 4 [0 0 0 0 1 1 1 1] 0 1 4 4 [0 0 0 0 1 1 1 1] 0 1 "Pw" [' +
                   " ".join(f(v) for v in pts) + "]")

    def subdivision(self):
        r = self.r
        scheme = r.choice(["catmull-clark", "bilinear", "loop"])
        if scheme == "loop":
            self.w('SubdivisionMesh "loop" [3 3 3 3] [0 1 2 0 2 3 0 3 1 1 3 2] [] [] [] [] '
                   '"P" [0 0 1 0.94 0 -0.33 -0.47 0.82 -0.33 -0.47 -0.82 -0.33]')
            return
        tags = '["crease" "corner"] [2 1 1 1] [0 1 2] [' + f(r.uniform(0, 5)) + " " + f(r.uniform(0, 5)) + "]" \
            if r.random() < 0.5 else "[] [] [] []"
        self.w(f'SubdivisionMesh "{scheme}" [4 4 4 4 4 4] [0 1 3 2 2 3 5 4 4 5 7 6 6 7 1 0 1 7 5 3 6 0 2 4] {tags} '
               '"P" [-0.5 -0.5 0.5 0.5 -0.5 0.5 -0.5 0.5 0.5 0.5 0.5 0.5 -0.5 0.5 -0.5 0.5 0.5 -0.5 '
               '-0.5 -0.5 -0.5 0.5 -0.5 -0.5]')

    def curves(self):
        r = self.r
        if r.random() < 0.5:
            n = r.randint(1, 20)
            self.w('Points "P" [' + floats(r, 3 * n, -1, 1) + '] "constantwidth" [' + f(r.uniform(0.02, 0.2)) + "]")
            return
        kind = r.choice(["linear", "cubic"])
        nv = 4 if kind == "cubic" else r.randint(2, 6)
        self.w(f'Curves "{kind}" [{nv}] "nonperiodic" "P" [' + floats(r, 3 * nv, -1, 1) +
               '] "constantwidth" [' + f(r.uniform(0.02, 0.2)) + "]")

    def attributes(self):
        r = self.r
        if r.random() < 0.7:
            self.w("Color " + floats(r, 3, 0, 1))
        if r.random() < 0.2:
            self.w("Opacity " + floats(r, 3, 0.3, 1))
        if r.random() < 0.3:
            self.w("ShadingRate " + f(r.choice([0.25, 0.5, 1, 2, 4, 16])))
        if r.random() < 0.2:
            self.w("Sides 1")
        if r.random() < 0.2:
            self.w("ReverseOrientation")
        if r.random() < 0.2:
            self.w('ShadingInterpolation "smooth"')
        if r.random() < 0.15:
            self.w('Attribute "visibility" "transmission" [0]')
        if r.random() < 0.1:
            self.w("Matte 1")
        if r.random() < 0.3:
            self.w('Attribute "dice" "binary" [1]')
        s = r.choice(SURFACES)
        if s == "paintedplastic" and self.texture:
            self.w('Surface "paintedplastic" "texturename" ["tex.tx"]')
        else:
            self.w(f'Surface "{s}"')
        if r.random() < 0.15:
            self.w('Attribute "displacementbound" "sphere" [0.2]')
            self.w('Displacement "bumpy" "Km" [0.1]' + (' "texturename" ["tex.tx"]' if self.texture else ""))

    def transform(self):
        r = self.r
        self.w("Translate " + floats(self.r, 3, -1.5, 1.5))
        self.w(f"Rotate {f(r.uniform(0, 360))} " + floats(r, 3, 0.1, 1))
        if r.random() < 0.3:
            self.w("Scale " + floats(r, 3, 0.3, 1.5))

    def object(self):
        r = self.r
        self.w("AttributeBegin")
        self.transform()
        self.attributes()
        moving = self.motion and r.random() < 0.3
        if moving:
            self.w("MotionBegin [0 1]")
            self.w("Translate " + floats(r, 3, -0.3, 0.3))
            self.w("Translate " + floats(r, 3, -0.3, 0.3))
            self.w("MotionEnd")
        r.choice([self.quadric, self.quadric, self.polygon, self.patch, self.subdivision, self.curves])()
        self.w("AttributeEnd")

    def light(self, k):
        r = self.r
        kind = r.choice(["shadowspot", "shadowdistant", "shadowpoint", "pointlight", "spotlight", "distantlight",
                         "ambientlight"])
        frm = floats(r, 3, -4, 4)
        frm = " ".join([frm.split()[0], f(r.uniform(2, 5)), f(r.uniform(-6, -2))])
        params = f'"intensity" [{f(r.uniform(0.3, 20 if "point" in kind or "spot" in kind else 1.2))}]'
        if kind != "ambientlight":
            params += f' "from" [{frm}]'
        if kind in ("shadowspot", "spotlight", "shadowdistant", "distantlight"):
            params += ' "to" [0 0 0]'
        if kind.startswith("shadow"):
            params += ' "shadowname" ["auto"]'
            if r.random() < 0.5:
                params += f' "samples" [{r.choice([1, 4, 16, 32])}] "blur" [{f(r.uniform(0, 0.05))}]'
            if r.random() < 0.3:
                params += ' "bias0" [0.01] "bias1" [0.1]'
        if kind in ("shadowspot", "spotlight"):
            params += f' "coneangle" [{f(r.uniform(0.2, 0.8))}]'
        self.w(f'LightSource "{kind}" {k} {params}')

    def options(self, name):
        r = self.r
        xres, yres = r.randint(8, 96), r.randint(8, 72)
        self.w(f"Format {xres} {yres} 1")
        self.w(f"PixelSamples {r.randint(1, 4)} {r.randint(1, 4)}")
        self.w(f'PixelFilter "{r.choice(FILTERS)}" {f(r.uniform(1, 4))} {f(r.uniform(1, 4))}')
        if r.random() < 0.5:
            self.w(f'Hider "hidden" "depthfilter" "{r.choice(DEPTH_FILTERS)}"' +
                   (' "jitter" [0]' if r.random() < 0.3 else ""))
        if r.random() < 0.3:
            self.w(f'Option "limits" "bucketsize" [{r.choice([4, 8, 16, 32])} {r.choice([4, 8, 16, 32])}] '
                   f'"gridsize" [{r.choice([16, 64, 256])}]')
        if r.random() < 0.3:
            self.w(f'Option "umbra" "shadowmapsize" [{r.choice([32, 64, 128, 256])}]')
        if r.random() < 0.2:
            self.w(f"Exposure {f(r.uniform(0.5, 2))} {f(r.uniform(0.8, 2.2))}")
        self.motion = r.random() < 0.2
        if self.motion:
            self.w("Shutter 0 1")
        mode = r.choice(["rgba", "rgb", "rgbaz", "z"])
        self.w(f'Display "{name}.{r.choice(["tif", "exr"])}" "file" "{mode}"')
        if r.random() < 0.5:
            self.w(f'Projection "perspective" "fov" [{f(r.uniform(20, 70))}]')
            if r.random() < 0.1:
                self.w("DepthOfField 2.8 0.2 6")
        else:
            self.w('Projection "orthographic"')
            self.w("ScreenWindow -3 3 -2.5 2.5")
        self.w("Translate 0 0 6")

    def texture_frame(self):
        self.w("FrameBegin 0")
        self.w("Format 16 16 1")
        self.w('Display "tex.tif" "file" "rgba"')
        self.w('Projection "perspective" "fov" [40]')
        self.w("Translate 0 0 4")
        self.w("WorldBegin")
        self.w('Surface "constant"')
        self.w("Color " + floats(self.r, 3, 0, 1))
        self.w("Sphere 1.5 -1.5 1.5 360")
        self.w("WorldEnd")
        self.w("FrameEnd")
        self.w('MakeTexture "tex.tif" "tex.tx" "periodic" "clamp" "gaussian" 2 2')

    def make(self):
        r = self.r
        self.w('Option "searchpath" "shader" ["' + os.path.join(ROOT, "shaders_dsl") + ':&"]')
        if self.texture:
            self.texture_frame()
        self.w("FrameBegin 1")
        self.options("out")
        self.w("WorldBegin")
        for k in range(r.randint(1, 4)):
            self.light(k + 1)
        if r.random() < 0.1:
            self.w('Atmosphere "fog" "distance" [20]')
        for _ in range(r.randint(1, 12)):
            self.object()
        if r.random() < 0.5:  # a receiver for the shadows
            self.w('AttributeBegin Surface "matte" Translate 0 -1.5 0 Rotate 90 1 0 0 '
                   'Polygon "P" [-4 -4 0 4 -4 0 4 4 0 -4 4 0] AttributeEnd')
        self.w("WorldEnd")
        self.w("FrameEnd")
        return "\n".join(self.lines) + "\n"


def run_one(umbra, seed, args, workdir):
    rib = os.path.join(workdir, f"scene{seed}.rib")
    with open(rib, "w") as out:
        out.write(Scene(seed).make())
    env = dict(os.environ)
    env["ASAN_OPTIONS"] = (f"detect_leaks=1:abort_on_error=0:hard_rss_limit_mb={args.memory_mb}:"
                           "allocator_may_return_null=1")
    env["UBSAN_OPTIONS"] = "print_stacktrace=1:halt_on_error=1"

    def limits():
        resource.setrlimit(resource.RLIMIT_CPU, (args.cpu_seconds, args.cpu_seconds + 5))
        if not args.sanitized:  # AddressSanitizer reserves terabytes of address space
            limit = args.memory_mb << 20
            resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    start = time.time()
    try:
        p = subprocess.run(["/usr/bin/time", "-f", "umbra-soak-peak-kb %M", umbra, "render", "--threads",
                            str(args.threads), "--quiet", rib], cwd=workdir, env=env, capture_output=True,
                           text=True, errors="replace", timeout=args.wall_seconds, preexec_fn=limits)
        out, rc, hung = p.stderr + p.stdout, p.returncode, False
    except subprocess.TimeoutExpired as e:
        err = e.stderr.decode(errors="replace") if isinstance(e.stderr, bytes) else (e.stderr or "")
        out, rc, hung = err, -1, True
    seconds = time.time() - start
    peak = 0
    for line in out.splitlines():
        if line.startswith("umbra-soak-peak-kb"):
            peak = int(line.split()[1])
    if hung:
        verdict = "hang"
    elif "LeakSanitizer" in out:
        verdict = "leak"
    elif "AddressSanitizer" in out or "runtime error:" in out or "Command terminated by signal" in out:
        verdict = "crash"
    elif "out of memory" in out or "hard rss limit" in out:
        verdict = "memory"
    elif rc != 0 or ": error:" in out:
        verdict = "error"
    else:
        verdict = "ok"
    warnings = out.count(": warning:")
    return verdict, peak, seconds, warnings, out, rib


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--umbra", required=True, help="the umbra binary (an AddressSanitizer build)")
    ap.add_argument("--count", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1, help="first scene's seed")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--memory-mb", type=int, default=2048, help="peak memory allowed a scene")
    ap.add_argument("--cpu-seconds", type=int, default=120)
    ap.add_argument("--wall-seconds", type=int, default=180)
    ap.add_argument("--not-sanitized", dest="sanitized", action="store_false",
                    help="a build without AddressSanitizer: limit the address space too")
    ap.add_argument("--failures", default="soak-failures", help="where failing scenes and logs are kept")
    ap.add_argument("--keep", action="store_true", help="keep every scene's directory")
    args = ap.parse_args()
    umbra = os.path.abspath(args.umbra)
    counts = {}
    peaks = []
    os.makedirs(args.failures, exist_ok=True)
    for seed in range(args.seed, args.seed + args.count):
        workdir = tempfile.mkdtemp(prefix=f"umbra-soak-{seed}-")
        verdict, peak, seconds, warnings, out, rib = run_one(umbra, seed, args, workdir)
        if "LeakSanitizer has encountered a fatal error" in out:
            # LeakSanitizer's own thread failed while it stopped the others
            # (it reports nothing about umbra): the scene is run again and
            # counted as such a failure only when the second run is clean.
            shutil.rmtree(workdir, ignore_errors=True)
            workdir = tempfile.mkdtemp(prefix=f"umbra-soak-{seed}-")
            verdict, peak, seconds, warnings, out, rib = run_one(umbra, seed, args, workdir)
            if verdict == "ok":
                verdict = "lsan-failed-then-ok"
        counts[verdict] = counts.get(verdict, 0) + 1
        peaks.append(peak)
        print(f"scene {seed}: {verdict} peak {peak / 1024:.0f} MB {seconds:.1f} s {warnings} warnings", flush=True)
        if verdict not in ("ok", "lsan-failed-then-ok"):
            shutil.copy(rib, args.failures)
            with open(os.path.join(args.failures, f"scene{seed}.log"), "w") as log:
                log.write(out)
            print("\n".join(out.splitlines()[-15:]), flush=True)
        if not args.keep:
            shutil.rmtree(workdir, ignore_errors=True)
    peaks.sort()
    n = len(peaks)
    print(f"{n} scenes: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    if n:
        print(f"peak memory: median {peaks[n // 2] / 1024:.0f} MB, max {peaks[-1] / 1024:.0f} MB")
    return 0 if counts.get("ok", 0) + counts.get("lsan-failed-then-ok", 0) == n else 1


if __name__ == "__main__":
    sys.exit(main())
