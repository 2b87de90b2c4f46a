#!/usr/bin/env python3
"""Writes the RIB scenes of the shadow quality study (docs/shadow-quality.md).

Run from anywhere: python3 scenes/quality/make_scenes.py. The scenes are
checked in; this script documents how their solids were built and rebuilds
them when a dimension changes. World units are metres-ish: the floor is a
few units across, y is up. Solids are closed Sides 1 surfaces whose
polygons wind so that the outward normal is (v1-v0) x (v2-v0) in a
right-handed frame, which umbra's default left-handed "outside"
orientation treats as the front; quadrics are capped with disks. Floors
are open Sides 2 surfaces.
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def num(x):
    s = '%.6g' % x
    return '0' if s == '-0' else s


def box(x0, x1, y0, y1, z0, z1):
    """Six faces of an axis-aligned box, outward winding."""
    return [
        [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],
        [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
        [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],
        [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],
        [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],
        [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],
    ]


def polygons(faces, indent='    '):
    return '\n'.join(indent + 'Polygon "P" [' + '  '.join(' '.join(num(c) for c in p) for p in f) + ']'
                     for f in faces)


def l_solid(x0, x1, xa, y0, y1, ya, z0, z1):
    """An L-shaped prism: a vertical bar x in [x0, xa], y in [y0, y1] on a
    foot x in [x0, x1], y in [y0, ya], extruded over z in [z0, z1]. Each cap
    is two rectangles (the cap is concave), the walls are six quads."""
    def cap(z, outward):
        rects = [[(x0, y0), (x1, y0), (x1, ya), (x0, ya)], [(x0, ya), (xa, ya), (xa, y1), (x0, y1)]]
        faces = []
        for r in rects:
            f = [(x, y, z) for x, y in r]  # counter-clockwise seen from +z: normal +z
            faces.append(f if outward > 0 else f[::-1])
        return faces
    outline = [(x0, y0), (x1, y0), (x1, ya), (xa, ya), (xa, y1), (x0, y1)]  # counter-clockwise from +z
    walls = []
    for i in range(len(outline)):
        (ax, ay), (bx, by) = outline[i], outline[(i + 1) % len(outline)]
        # (b - a) x (+z) points out of a counter-clockwise outline.
        walls.append([(ax, ay, z0), (bx, by, z0), (bx, by, z1), (ax, ay, z1)])
    return cap(z1, +1) + cap(z0, -1) + walls


def floor(half, y=0.0):
    return ('  AttributeBegin\n'
            '    Attribute "identifier" "name" ["floor"]\n'
            '    Sides 2\n'
            '    Polygon "P" [%s]\n'
            '  AttributeEnd\n') % '  '.join(
                ' '.join(num(c) for c in p) for p in [(-half, y, -half), (-half, y, half), (half, y, half), (half, y, -half)])


def solid(name, body):
    return ('  AttributeBegin\n'
            '    Attribute "identifier" "name" ["%s"]\n'
            '    Sides 1\n%s\n'
            '  AttributeEnd\n') % (name, body)


def capped_cylinder(radius, height, indent='    '):
    """A closed cylinder along +z from 0 to height: wall and two disks (the
    bottom one turned over so its normal points down, out of the solid)."""
    return (f'{indent}Cylinder {num(radius)} 0 {num(height)} 360\n'
            f'{indent}TransformBegin Translate 0 0 {num(height)} Disk 0 {num(radius)} 360 TransformEnd\n'
            f'{indent}TransformBegin Rotate 180 1 0 0 Disk 0 {num(radius)} 360 TransformEnd')


def camera(distance, pitch, yaw, target):
    """A camera `distance` from `target`, looking down by `pitch` degrees
    and turned by `yaw` degrees about the vertical axis."""
    return (f'Translate 0 0 {num(distance)}\nRotate {num(-pitch)} 1 0 0\nRotate {num(yaw)} 0 1 0\n'
            f'Translate {num(-target[0])} {num(-target[1])} {num(-target[2])}')


def scene(path, title, camera, light, world, frame_note):
    text = f"""##RenderMan RIB
# {title}
{frame_note}
# The shadow quality study (scripts/shadow_quality.py) replaces the Display
# line, adds its Options, and sets the light's "shadowname" (auto map or
# "raytrace") and "bias". Render by hand from this folder:
#   umbra render {os.path.basename(path)}
version 3.04
Option "searchpath" "shader" ["shaders:&"]
Display "{os.path.splitext(os.path.basename(path))[0]}.tif" "file" "rgba"
Format 256 192 1
PixelSamples 2 2
PixelFilter "box" 1 1
ShadingRate 1
Option "umbra" "shadowmapsize" [512]
Option "umbra" "depthfilter" ["second"]
Option "umbra" "depthcull" ["none"]
Projection "perspective" "fov" [40]
{camera}
WorldBegin
  Surface "shadowterm"
  {light}
{world}WorldEnd
"""
    with open(path, 'w') as f:
        f.write(text)


def main():
    # Wang & Molnar Fig. 4: a table whose legs touch the floor.
    legs = []
    for x in (-1.05, 0.95):
        for z in (-0.65, 0.55):
            legs += box(x, x + 0.1, 0.0, 1.0, z, z + 0.1)
    world = floor(3.0) + solid('tabletop', polygons(box(-1.2, 1.2, 1.0, 1.1, -0.75, 0.75))) + \
        solid('legs', polygons(legs))
    scene(os.path.join(HERE, 'table.rib'),
          'Wang & Molnar 1994, Figure 4: a table whose legs touch the floor, lit from above at a slant.',
          camera(7.5, 40, 15, (0, 0.0, -0.8)),
          'LightSource "qspot" "key" "from" [2.2 5 2.6] "to" [0 0.4 0] "coneangle" [0.5] "shadowname" ["auto"]',
          world, '# No constant bias is right for both the floor (acne) and the legs (shadows detach).')

    # Weiskopf & Ertl Fig. 5: an L-shaped solid above a plane, light from right above.
    world = floor(2.5) + solid('L', polygons(l_solid(-1.0, 1.0, -0.5, 0.4, 1.9, 0.85, -0.5, 0.5)))
    scene(os.path.join(HERE, 'lshape.rib'),
          'Weiskopf & Ertl 2003, Figure 5: an L-shaped solid above a plane; directional light from right above.',
          camera(6.5, 30, -25, (0, 0.3, -0.8)),
          'LightSource "qdistant" "key" "from" [1.2 4 0.6] "to" [0 0 0] "shadowname" ["auto"]',
          world, '# Self-unshadowing at the inner crease, self-shadowing at light silhouettes.')

    # Weiskopf & Ertl Fig. 6: a double torus (here two linked tori).
    tori = ('    TransformBegin Translate -0.45 1.1 0 Rotate 90 1 0 0 Torus 0.7 0.22 0 360 360 TransformEnd\n'
            '    TransformBegin Translate 0.45 1.1 0 Torus 0.7 0.22 0 360 360 TransformEnd')
    world = floor(3.0) + solid('tori', tori)
    scene(os.path.join(HERE, 'tori.rib'),
          'Weiskopf & Ertl 2003, Figure 6: a double torus, here two linked tori, over a plane.',
          camera(7.0, 38, 20, (0, 0.2, -0.8)),
          'LightSource "qspot" "key" "from" [-2 5 1.5] "to" [0 0.6 0] "coneangle" [0.45] "shadowname" ["auto"]',
          world, '# Curved solids shadowing themselves and each other.')

    # Wang & Molnar Fig. 7: a thin slab, first and second surfaces close together.
    world = floor(3.0) + solid('slab', '    TransformBegin Translate 0 0.7 0 Rotate 20 0 0 1 Rotate -15 1 0 0\n' +
                              polygons(box(-1.0, 1.0, -0.015, 0.015, -0.8, 0.8), '      ') + '\n    TransformEnd')
    scene(os.path.join(HERE, 'slab.rib'),
          'Wang & Molnar 1994, Figure 7: a thin tilted slab (0.03 units thick) over a plane.',
          camera(6.5, 38, 10, (0, 0.0, -0.6)),
          'LightSource "qspot" "key" "from" [-2.5 4.5 1] "to" [0 0.4 0] "coneangle" [0.5] "shadowname" ["auto"]',
          world, '# The slab is thinner than a 256-texel map footprint at a grazing light.')

    # Reeves, Salesin & Cook 1987: a sphere over a plane.
    sphere = '    Translate -0.1 1.0 0\n    Sphere 0.7 -0.7 0.7 360'
    world = floor(3.0) + solid('sphere', sphere)
    scene(os.path.join(HERE, 'sphere.rib'),
          "Reeves, Salesin & Cook 1987, Figures 5-6: a sphere over a plane (here the plane casts too).",
          camera(7.0, 32, 0, (0.3, 0.1, -0.6)),
          'LightSource "qspot" "key" "from" [-3 4.5 1.5] "to" [0 0.5 0] "coneangle" [0.45] "shadowname" ["auto"]',
          world, '# The sphere\'s terminator is where first-depth maps show acne.')


if __name__ == '__main__':
    main()
