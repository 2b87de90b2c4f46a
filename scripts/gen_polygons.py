#!/usr/bin/env python3
"""Writes a RIB of N separate Polygon requests (a grid of small quads
facing the camera, one attribute state), or with --mesh the same quads as
one PointsPolygons: the pair docs/performance.md measures the scene
builder's memory with.

    scripts/gen_polygons.py 1000000 > /tmp/polys.rib
    /usr/bin/time -v build/bin/umbra /tmp/polys.rib
"""
import argparse
import math
import sys


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("count", type=int, help="number of quads")
    ap.add_argument("--mesh", action="store_true", help="one PointsPolygons instead of separate Polygons")
    ap.add_argument("--output", default="polygons.tif", help="the Display's file name")
    args = ap.parse_args()
    n = args.count
    side = max(1, math.ceil(math.sqrt(n)))
    size = 2.0 / side
    out = sys.stdout
    out.write(f'Display "{args.output}" "file" "rgba"\nFormat 160 120 1\nPixelSamples 2 2\n')
    out.write('Projection "perspective" "fov" [45]\nTranslate 0 0 3\nWorldBegin\n')
    out.write('LightSource "distantlight" 1 "intensity" [1]\nSurface "matte"\n')
    corners = []
    for k in range(n):
        x0 = -1 + (k % side) * size
        y0 = -1 + (k // side) * size
        x1, y1 = x0 + size * 0.9, y0 + size * 0.9
        corners.append((x0, y0, x1, y1))
    if args.mesh:
        out.write("PointsPolygons [" + " ".join("4" for _ in range(n)) + "]\n[")
        out.write(" ".join(f"{4*k} {4*k+1} {4*k+2} {4*k+3}" for k in range(n)))
        out.write(']\n"P" [')
        for x0, y0, x1, y1 in corners:
            out.write(f"{x0:.5g} {y0:.5g} 0 {x1:.5g} {y0:.5g} 0 {x1:.5g} {y1:.5g} 0 {x0:.5g} {y1:.5g} 0\n")
        out.write("]\n")
    else:
        for x0, y0, x1, y1 in corners:
            out.write(f'Polygon "P" [{x0:.5g} {y0:.5g} 0 {x1:.5g} {y0:.5g} 0 {x1:.5g} {y1:.5g} 0 {x0:.5g} {y1:.5g} 0]\n')
    out.write("WorldEnd\n")


if __name__ == "__main__":
    main()
