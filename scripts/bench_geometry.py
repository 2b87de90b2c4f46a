#!/usr/bin/env python3
"""Production-geometry benchmark (issue 17): a subdivision-heavy frame and a
hair frame, generated here (the RIBs are megabytes, so they are not kept in
the repository), rendered by umbra and, when the peer renderers are beside
the project (../shared/peers), by Pixie 2.2.6 on the same RIB.

Scenes (640x480, PixelSamples 4 4, ShadingRate 1, one distant light):
  subdiv      25 Catmull-Clark tori of 64x64 quads each (102,400 base faces),
              a crease ring on each, displaced by a shader written here
  subdiv_flat the same tori without creases or displacement
  bspline     the same control meshes as periodic bicubic B-spline
              PatchMeshes: the limit surface of a regular Catmull-Clark mesh
              *is* that B-spline surface, so subdiv_flat / bspline is the
              cost of subdivision per micropolygon against bicubic patches
  hair        100,000 cubic B-spline curves (4 vertices, constant width
              0.004) grown from a sphere

Prints, per scene and renderer: best wall time of RUNS runs (alternating the
renderers, since this machine's speed drifts with its host's load), peak
resident memory, umbra's micropolygons and micropolygons per second.

  python3 scripts/bench_geometry.py [--runs N] [--threads N] [--keep DIR] [--patchblock N]

--patchblock N puts `Attribute "umbra" "patchblock" [N]` in umbra's copy of
each scene (0: bicubic PatchMeshes diced patch by patch, as before blocks;
default: the renderer's own, 8 x 8 patches a block).
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

from timed_run import run

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
UMBRA = os.path.join(ROOT, "build", "bin", "umbra")
PEERS = os.environ.get("UMBRA_PEERS", os.path.join(ROOT, "..", "shared", "peers"))
PIXIE = os.path.join(PEERS, "bin", "pixie-rndr")
PIXIE_SDRC = os.path.join(PEERS, "bin", "pixie-sdrc")

GRID = 64          # quads around each torus, both ways
TORI = 5           # TORI x TORI tori
HAIRS = 100_000

RIPPLES_SL = """
displacement ripples(float Km = 0.015; float freq = 40) {
    point Po = transform("object", P);
    P += Km * sin(freq * xcomp(Po)) * sin(freq * ycomp(Po)) * normalize(N);
    N = calculatenormal(P);
}
"""

HEADER = """Display "{name}.tif" "file" "rgba"
Format 640 480 1
PixelSamples 4 4
ShadingRate 1
Projection "perspective" "fov" [40]
Translate 0 0 {distance}
WorldBegin
LightSource "ambientlight" 1 "intensity" [0.15]
LightSource "distantlight" 2 "from" [1 2 -2] "to" [0 0 0] "intensity" [1]
"""


def torus_points(n):
    """Control points of an n x n torus mesh, major radius 1, minor 0.35."""
    pts = []
    for j in range(n):
        phi = 2 * math.pi * j / n
        for i in range(n):
            theta = 2 * math.pi * i / n
            r = 1 + 0.35 * math.cos(phi)
            pts.append((r * math.cos(theta), r * math.sin(theta), 0.35 * math.sin(phi)))
    return pts


def fmt(values):
    return " ".join("%.6g" % v for v in values)


def placed_tori(mesh):
    """The mesh request at each of the TORI x TORI places, then WorldEnd."""
    out = []
    for a in range(TORI):
        for b in range(TORI):
            x, y, rot = (a - (TORI - 1) / 2) * 2.6, (b - (TORI - 1) / 2) * 2.6, 20 * a + 13 * b
            out.append("AttributeBegin\nTranslate %g %g 0\nRotate %g 1 1 0\n%sAttributeEnd\n" % (x, y, rot, mesh))
    out.append("WorldEnd\n")
    return "".join(out)


def subdiv_scene(name, creases_and_displacement):
    n = GRID
    pts = torus_points(n)
    verts = []
    for j in range(n):
        for i in range(n):
            a, b = j * n + i, j * n + (i + 1) % n
            c, d = ((j + 1) % n) * n + (i + 1) % n, ((j + 1) % n) * n + i
            verts += [a, b, c, d]
    nverts = " ".join(["4"] * (n * n))
    # Pixie draws nothing of a SubdivisionMesh without tag arrays, so the
    # plain mesh gives an empty tag list.
    tags = "[] [] [] []"
    if creases_and_displacement:
        ring = list(range(n)) + [0]
        tags = '["crease"] [%d 1] [%s] [2]' % (len(ring), " ".join(map(str, ring)))
    out = [HEADER.format(name=name, distance=19)]
    if creases_and_displacement:
        out.append('Attribute "displacementbound" "sphere" [0.015]\nDisplacement "ripples"\n')
    out.append('Surface "plastic"\n')
    mesh = 'SubdivisionMesh "catmull-clark" [%s] [%s] %s "P" [%s]\n' % (
        nverts, " ".join(map(str, verts)), tags, fmt(c for p in pts for c in p))
    return "".join(out) + placed_tori(mesh)


def bspline_scene(name):
    n = GRID
    pts = torus_points(n)
    out = [HEADER.format(name=name, distance=19), 'Surface "plastic"\nBasis "b-spline" 1 "b-spline" 1\n']
    # PatchMesh is u-major: u runs fastest, as the torus points do (i fastest).
    mesh = 'PatchMesh "bicubic" %d "periodic" %d "periodic" "P" [%s]\n' % (n, n, fmt(c for p in pts for c in p))
    return "".join(out) + placed_tori(mesh)


def hair_scene(name):
    out = [HEADER.format(name=name, distance=5), 'Surface "plastic" "Ks" [0.3] "roughness" [0.2]\n',
           'Basis "b-spline" 1 "b-spline" 1\n', 'AttributeBegin\nColor 0.6 0.4 0.2\nSphere 1 -1 1 360\nAttributeEnd\n']
    golden = math.pi * (3 - math.sqrt(5))
    per_request = 10_000
    for start in range(0, HAIRS, per_request):
        pts = []
        for k in range(start, start + per_request):
            z = 1 - 2 * (k + 0.5) / HAIRS
            r = math.sqrt(1 - z * z)
            a = golden * k
            d = (r * math.cos(a), r * math.sin(a), z)
            # A hair leaves the surface along the normal and curls sideways.
            side = (-math.sin(a), math.cos(a), 0)
            for s in range(4):
                h = 0.12 * s
                curl = 0.04 * s * s
                pts += [d[c] * (1 + h) + side[c] * curl for c in range(3)]
        out.append('Curves "cubic" [%s] "nonperiodic" "P" [%s] "constantwidth" [0.004]\n' % (
            " ".join(["4"] * per_request), fmt(pts)))
    out.append("WorldEnd\n")
    return "".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--keep", help="write the scenes and images here and keep them")
    ap.add_argument("--scenes", default="subdiv,subdiv_flat,bspline,hair")
    ap.add_argument("--patchblock", type=int, help="Attribute \"umbra\" \"patchblock\" for umbra's renders")
    args = ap.parse_args()
    if not os.access(UMBRA, os.X_OK):
        sys.exit("build umbra first (scripts/build.sh)")
    work = args.keep or tempfile.mkdtemp(prefix="umbra-geom-bench-")
    os.makedirs(work, exist_ok=True)
    makers = {"subdiv": lambda n: subdiv_scene(n, True), "subdiv_flat": lambda n: subdiv_scene(n, False),
              "bspline": bspline_scene, "hair": hair_scene}
    with open(os.path.join(work, "ripples.sl"), "w") as f:
        f.write(RIPPLES_SL)
    pixie = os.access(PIXIE, os.X_OK)
    if pixie:
        pixie = run([PIXIE_SDRC, "ripples.sl"], work, peer=True) is not None
    else:
        print("(no peers at %s: umbra's figures alone)" % PEERS)
    print("%-12s %-7s %9s %10s %14s %12s" % ("scene", "renderer", "wall (s)", "peak MiB", "micropolygons", "Mmp/s"))
    try:
        for name in args.scenes.split(","):
            rib = name + ".rib"
            text = makers[name](name)
            with open(os.path.join(work, rib), "w") as f:
                f.write(text)
            umbra_rib = rib
            if args.patchblock is not None:
                # Pixie would warn about an attribute it does not know: umbra
                # alone reads this copy.
                umbra_rib = name + ".umbra.rib"
                with open(os.path.join(work, umbra_rib), "w") as f:
                    f.write(text.replace("WorldBegin\n", 'WorldBegin\nAttribute "umbra" "patchblock" [%d]\n'
                                         % args.patchblock, 1))
            best = {}
            for _ in range(args.runs):
                wall, rss = run([UMBRA, "render", umbra_rib, "--threads", str(args.threads), "--quiet",
                                 "--stats", name + ".json"], work)
                best["umbra"] = min(best.get("umbra", (1e30, 0)), (wall, rss))
                if pixie:
                    ran = run([PIXIE, "-t:%d" % args.threads, rib], work, peer=True)
                    if ran is None:
                        pixie = False
                    else:
                        best["pixie"] = min(best.get("pixie", (1e30, 0)), ran)
            with open(os.path.join(work, name + ".json")) as f:
                mp = json.load(f)["frames"][0]["passes"][-1]["counts"]["micropolygons"]
            wall, rss = best["umbra"]
            print("%-12s %-7s %9.2f %10.0f %14d %12.2f" % (name, "umbra", wall, rss, mp, mp / wall / 1e6))
            if pixie and "pixie" in best:
                pw, prss = best["pixie"]
                print("%-12s %-7s %9.2f %10.0f %14s %12s   umbra/pixie %.2f" % (name, "pixie", pw, prss, "", "",
                                                                               wall / pw))
            sys.stdout.flush()
    finally:
        if not args.keep:
            shutil.rmtree(work)


if __name__ == "__main__":
    main()
