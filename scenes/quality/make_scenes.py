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

The first five scenes follow the papers' figures. The rest are written the
way users' and exporters' RIB is: everything Sides 2, receivers that are
open patches, lights at grazing angles, objects resting on each other, a
camera mirrored by `Scale 1 1 -1` before its transform and a light declared
under a mirroring transform.
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


def solid(name, body, sides=1):
    return ('  AttributeBegin\n'
            '    Attribute "identifier" "name" ["%s"]\n'
            '    Sides %d\n%s\n'
            '  AttributeEnd\n') % (name, sides, body)


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


def mirrored_camera(distance, pitch, yaw, target):
    """The view camera() gives of the world mirrored in z, written as
    exporters write it: `Scale 1 1 -1` to a right-handed camera space, then
    a rigid camera transform (the world's z runs the other way)."""
    return (f'Scale 1 1 -1\nTranslate 0 0 {num(-distance)}\nRotate {num(pitch)} 1 0 0\nRotate {num(-yaw)} 0 1 0\n'
            f'Translate {num(-target[0])} {num(-target[1])} {num(target[2])}')


def distant_from(elevation, azimuth, distance=5.0):
    """A point `distance` from the origin seen `elevation` degrees above the
    floor, `azimuth` degrees from +x towards +z."""
    e, a = math.radians(elevation), math.radians(azimuth)
    return [distance * math.cos(e) * math.cos(a), distance * math.sin(e), distance * math.cos(e) * math.sin(a)]


def vec(v):
    return '[' + ' '.join(num(c) for c in v) + ']'


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

    user_scenes()


def user_scenes():
    # A distant light 5, 10 and 20 degrees above an open floor: a cube resting
    # on it (contact along four edges) and a post, Sides 1 as modellers close
    # solids. At 5 degrees a map texel spans 11 times its width on the floor.
    for elevation in (5, 10, 20):
        world = floor(3.0) + solid('cube', polygons(box(-1.6, -0.9, 0.0, 0.7, -0.9, -0.2))) + \
            solid('post', polygons(box(-1.2, -1.05, 0.0, 1.2, 0.5, 0.65)))
        scene(os.path.join(HERE, f'grazing{elevation}.rib'),
              f'A distant light {elevation} degrees above an open floor: a cube resting on it and a post.',
              camera(7.0, 35, 10, (0.2, 0.0, -0.3)),
              f'LightSource "qdistant" "key" "from" {vec(distant_from(elevation, 160))} "to" [0 0 0] '
              '"shadowname" ["auto"]',
              world, '# Grazing light: the floor is nearly edge-on to the map.')

    # A sphere resting on a larger sphere (a point contact between two curved
    # surfaces), both on the floor; spotlight.
    world = floor(3.0) + solid('spheres', '    TransformBegin Translate 0 0.8 0 Sphere 0.8 -0.8 0.8 360 TransformEnd\n'
                                          '    TransformBegin Translate 0 1.95 0 Sphere 0.35 -0.35 0.35 360 TransformEnd')
    scene(os.path.join(HERE, 'spheres.rib'),
          'A sphere resting on a larger sphere resting on an open floor; spotlight from the side.',
          camera(7.0, 25, 15, (0.2, 0.6, -0.6)),
          'LightSource "qspot" "key" "from" [-3.5 3.5 1.2] "to" [0 0.9 0] "coneangle" [0.5] "shadowname" ["auto"]',
          world, '# The small sphere shadows the large one\'s curved top; contact at single points.')

    # A torus standing on a cylinder lying on its side (curved receiver, point
    # contacts), the cylinder resting on the floor along a line; distant light.
    world = floor(3.0) + solid('cylinder', '    TransformBegin Translate 0 0.6 -1.1\n' +
                               capped_cylinder(0.6, 2.2, '      ') + '\n    TransformEnd') + \
        solid('torus', '    TransformBegin Translate 0 1.9 0 Rotate 90 0 1 0 Torus 0.55 0.15 0 360 360 TransformEnd')
    scene(os.path.join(HERE, 'torus_cylinder.rib'),
          'A torus standing on a capped cylinder lying on an open floor; distant light from the side.',
          camera(7.0, 28, 25, (0, 0.8, -0.4)),
          f'LightSource "qdistant" "key" "from" {vec(distant_from(40, 70))} "to" [0 0 0] "shadowname" ["auto"]',
          world, '# The torus casts onto the cylinder\'s curved wall; the cylinder onto the floor.')

    # A stool (four legs touching the floor) and a cube resting on the floor,
    # all Sides 2 as many exporters write every surface; spotlight.
    legs = []
    for x in (-0.7, 0.6):
        for z in (-0.7, 0.6):
            legs += box(x, x + 0.1, 0.0, 0.8, z, z + 0.1)
    world = floor(3.0) + solid('seat', polygons(box(-0.8, 0.8, 0.8, 0.88, -0.8, 0.8)), 2) + \
        solid('legs', polygons(legs), 2) + solid('cube', polygons(box(1.0, 1.6, 0.0, 0.6, -1.4, -0.8)), 2)
    scene(os.path.join(HERE, 'stool_sides2.rib'),
          'A stool whose legs touch the floor and a cube resting on it, every surface Sides 2; spotlight.',
          camera(7.5, 35, -20, (0.2, 0.0, -0.7)),
          'LightSource "qspot" "key" "from" [2.5 4 2.8] "to" [0 0.3 0] "coneangle" [0.55] "shadowname" ["auto"]',
          world, '# Two-sided solids: the map sees their back faces as surfaces too.')

    # Receivers that are open two-sided patches: a gently curved bicubic
    # ground and a bilinear wall, with a thin Sides 2 slab over them; spotlight.
    rows = []
    for j in range(4):
        for i in range(4):
            x, z = -3 + 2 * i, -3 + 2 * j
            y = 0.25 * math.sin(0.9 * x + 0.3) * math.cos(0.6 * z) - 0.1
            rows.append(f'{num(x)} {num(y)} {num(z)}')
    ground = ('  AttributeBegin\n    Attribute "identifier" "name" ["ground"]\n    Sides 2\n'
              '    Patch "bicubic" "P" [' + '  '.join(rows) + ']\n'
              '    Patch "bilinear" "P" [-3 -0.2 2.2  3 -0.2 2.2  -3 2 2.2  3 2 2.2]\n  AttributeEnd\n')
    world = ground + solid('slab', '    TransformBegin Translate 0.2 0.75 -0.4 Rotate 12 0 0 1 Rotate -8 1 0 0\n' +
                           polygons(box(-0.9, 0.9, -0.015, 0.015, -0.7, 0.7), '      ') + '\n    TransformEnd', 2)
    scene(os.path.join(HERE, 'patches.rib'),
          'Open two-sided patch receivers (a curved bicubic ground, a bilinear wall) under a thin Sides 2 slab.',
          camera(7.0, 30, 5, (0, 0.3, -0.6)),
          'LightSource "qspot" "key" "from" [-1.5 4.5 -3.5] "to" [0 0.3 0.4] "coneangle" [0.55] "shadowname" ["auto"]',
          world, '# Curved open receivers and a slab thinner than a texel\'s depth step.')

    # The table and a cube behind a camera mirrored as exporters write it.
    table_legs = []
    for x in (-1.05, 0.95):
        for z in (-0.65, 0.55):
            table_legs += box(x, x + 0.1, 0.0, 1.0, z, z + 0.1)
    world = floor(3.0) + solid('tabletop', polygons(box(-1.2, 1.2, 1.0, 1.1, -0.75, 0.75))) + \
        solid('legs', polygons(table_legs)) + solid('cube', polygons(box(1.4, 2.0, 0.0, 0.6, 0.9, 1.5)))
    scene(os.path.join(HERE, 'mirror_camera.rib'),
          'The table and a cube resting on the floor, camera mirrored by Scale 1 1 -1 before its transform.',
          mirrored_camera(7.5, 40, 15, (0, 0.0, -0.8)),
          'LightSource "qspot" "key" "from" [2.2 5 -2.6] "to" [0 0.4 0] "coneangle" [0.55] "shadowname" ["auto"]',
          world, '# A right-handed world seen through a mirroring camera, as exporters write it.')

    # A sphere resting on the floor and a cube resting on a plane, the
    # spotlight declared under a mirroring transform (its "from" and "to" are
    # mirrored back to the same place).
    world = floor(3.0) + solid('sphere', '    TransformBegin Translate -0.6 0.6 0.2 Sphere 0.6 -0.6 0.6 360 TransformEnd') + \
        solid('cube', polygons(box(0.5, 1.2, 0.0, 0.7, -0.9, -0.2)))
    scene(os.path.join(HERE, 'mirror_light.rib'),
          'A sphere and a cube resting on the floor; the spotlight is declared under Scale -1 1 1.',
          camera(7.0, 35, -10, (0, 0.2, -0.5)),
          'TransformBegin\n  Scale -1 1 1\n  LightSource "qspot" "key" "from" [2.5 4.5 1.8] "to" [0 0.3 0] '
          '"coneangle" [0.5] "shadowname" ["auto"]\n  TransformEnd',
          world, '# A mirrored light transform: the map is made in a mirrored light space.')


if __name__ == '__main__':
    main()
