#!/usr/bin/env python3
"""Writes production.rib, the production-frame benchmark of issue 21: a
1920x1080 frame, PixelSamples 4 4, gaussian 2x2, ShadingRate 0.5, about 520
objects (400 spheres, 60 tori, 60 displaced bicubic patches with a
displacementbound, a bilinear ground), plastic and matte, an ambient light
and three shadowed spotlights whose 2048^2 maps are rendered first as
RenderMan users do it (a light-view frame writing a zfile, then MakeShadow),
looked up with 16 samples.

The scene is checked in; this script documents it and rebuilds it:
    python3 scenes/bench/production/make_production.py
Its shaders (benchspot.sl, benchbumps.sl) are beside it, so umbra, Pixie
and Aqsis all run the same shading code.
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))


class Lcg:
    """A fixed pseudo-random sequence, so the scene never changes."""
    def __init__(self, seed):
        self.state = seed

    def next(self):
        self.state = (self.state * 1103515245 + 12345) % (1 << 31)
        return self.state / float(1 << 31)

    def range(self, a, b):
        return a + (b - a) * self.next()


def num(x):
    s = '%.5g' % x
    return '0' if s == '-0' else s


def look_at(eye, target, up=(0.0, 1.0, 0.0)):
    """A RenderMan (left-handed) camera at eye looking at target, as the
    row-vector matrix ConcatTransform takes."""
    def sub(a, b): return [a[i] - b[i] for i in range(3)]
    def norm(a):
        l = math.sqrt(sum(c * c for c in a))
        return [c / l for c in a]
    def cross(a, b): return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    def dot(a, b): return sum(a[i] * b[i] for i in range(3))
    z = norm(sub(target, eye))
    x = norm(cross(up, z))
    y = cross(z, x)
    rows = [x + [-dot(x, eye)], y + [-dot(y, eye)], z + [-dot(z, eye)], [0, 0, 0, 1]]
    return 'ConcatTransform [' + ' '.join(num(rows[j][i]) for i in range(4) for j in range(4)) + ']'


LIGHTS = [  # from, to, cone angle (radians)
    ((-12.0, 16.0, -10.0), (0.0, 0.0, 2.0), 0.62),
    ((14.0, 18.0, -6.0), (1.0, 0.0, 3.0), 0.58),
    ((2.0, 20.0, 14.0), (0.0, 0.0, 2.0), 0.55),
]


def world(rng_seed=7):
    rng = Lcg(rng_seed)
    out = []
    out.append('  AttributeBegin\n    Attribute "identifier" "name" ["ground"]\n    Surface "matte"\n'
               '    Color [0.6 0.6 0.55]\n    Patch "bilinear" "P" [-18 0 -12  18 0 -12  -18 0 18  18 0 18]\n'
               '  AttributeEnd\n')
    for k in range(400):
        r = rng.range(0.25, 0.55)
        x, z = rng.range(-15, 15), rng.range(-10, 16)
        out.append('  AttributeBegin\n    Translate %s %s %s\n    Color [%s %s %s]\n'
                   '    Surface "plastic" "roughness" [0.15]\n    Sphere %s %s %s 360\n  AttributeEnd\n' % (
                       num(x), num(r), num(z), num(rng.range(0.2, 1)), num(rng.range(0.2, 1)), num(rng.range(0.2, 1)),
                       num(r), num(-r), num(r)))
    for k in range(60):
        x, z = rng.range(-14, 14), rng.range(-9, 15)
        out.append('  AttributeBegin\n    Translate %s 0.2 %s\n    Rotate %s 0 1 0\n    Rotate 90 1 0 0\n'
                   '    Color [%s %s %s]\n    Surface "matte"\n    Torus 0.55 0.2 0 360 360\n  AttributeEnd\n' % (
                       num(x), num(z), num(rng.range(0, 180)), num(rng.range(0.3, 1)), num(rng.range(0.3, 1)),
                       num(rng.range(0.3, 1))))
    for k in range(60):
        x, z = rng.range(-14, 14), rng.range(-9, 15)
        pts = []
        for j in range(4):
            for i in range(4):
                pts += [i / 3.0 * 1.6 - 0.8, j / 3.0 * 1.6, 0.25 * math.sin(i * 1.7 + j * 2.3 + k)]
        out.append('  AttributeBegin\n    Translate %s 0 %s\n    Rotate %s 0 1 0\n    Color [%s %s %s]\n'
                   '    Attribute "displacementbound" "sphere" [0.06]\n'
                   '    Displacement "benchbumps" "Km" [0.06]\n    Surface "plastic"\n'
                   '    Patch "bicubic" "P" [%s]\n  AttributeEnd\n' % (
                       num(x), num(z), num(rng.range(0, 360)), num(rng.range(0.3, 1)), num(rng.range(0.3, 1)),
                       num(rng.range(0.3, 1)), ' '.join(num(c) for c in pts)))
    return ''.join(out)


def main():
    with open(os.path.join(HERE, 'world.rib'), 'w') as f:
        f.write('##RenderMan RIB\n# The production benchmark\'s world, read by every frame of production.rib.\n' + world())
    geometry = '  ReadArchive "world.rib"\n'
    parts = ['##RenderMan RIB\n# Written by make_production.py (see there): the production-frame benchmark of issue 21.\n'
             'version 3.04\nOption "searchpath" "shader" [".:&"]\n']
    for n, (frm, to, cone) in enumerate(LIGHTS, start=1):
        parts.append('FrameBegin %d\n  Display "light%d.z" "zfile" "z"\n  Format 2048 2048 1\n  PixelSamples 1 1\n'
                     '  PixelFilter "box" 1 1\n  ShadingRate 4\n  Projection "perspective" "fov" [%s]\n  %s\n'
                     'WorldBegin\n%sWorldEnd\nFrameEnd\nMakeShadow "light%d.z" "light%d.shd"\n' % (
                         n, n, num(math.degrees(2 * cone) + 2), look_at(frm, to), geometry, n, n))
    lights = '  LightSource "ambientlight" 1 "intensity" [0.08]\n'
    for n, (frm, to, cone) in enumerate(LIGHTS, start=1):
        lights += ('  LightSource "benchspot" %d "from" [%s] "to" [%s] "coneangle" [%s] "intensity" [%s] '
                   '"shadowname" ["light%d.shd"] "samples" [16]\n' % (
                       n + 1, ' '.join(num(c) for c in frm), ' '.join(num(c) for c in to), num(cone),
                       num(0.55 * sum(c * c for c in frm) / 1.0), n))
    parts.append('FrameBegin 4\n  Display "production.tif" "file" "rgba"\n  Format 1920 1080 1\n  PixelSamples 4 4\n'
                 '  PixelFilter "gaussian" 2 2\n  ShadingRate 0.5\n  Projection "perspective" "fov" [45]\n'
                 '  %s\nWorldBegin\n%s%sWorldEnd\nFrameEnd\n' % (look_at((0, 9, -19), (0, 0, 2)), lights, geometry))
    with open(os.path.join(HERE, 'production.rib'), 'w') as f:
        f.write(''.join(parts))


if __name__ == '__main__':
    main()
