#!/usr/bin/env python3
"""Writes an animation of scenes/reeves/desk_lamp.rib as one multi-frame RIB.

Each frame is the still scene with the camera orbiting the desk and, on the
frames the shot asks for, Junior turning his head (his lamp and his bulb's
light turn together) and the ball rolling. Frames where the lamps and the
ball stand still reuse their depth maps (docs/shadows.md).

  scripts/desk_lamp_animation.py --shot demo > scenes/reeves/desk_lamp_anim.rib
  scripts/desk_lamp_animation.py --shot camera --frames 12   # the benchmark
"""

import argparse
import math
import pathlib
import sys

SCENE = pathlib.Path(__file__).resolve().parent.parent / "scenes" / "reeves" / "desk_lamp.rib"

CAMERA = "Translate 0 -12 165\nRotate -28 1 0 0\nRotate 12 0 1 0\n"
JUNIOR_TURN = "Rotate 174 0 1 0"
BALL = "Translate 14 8 18"


def shot_pose(shot, frame, count):
    """(camera yaw in degrees, Junior's turn, ball x) of `frame` (1-based)."""
    t = (frame - 1) / max(1, count - 1)
    if shot == "camera":  # the camera orbits, nothing else moves
        return 12 - 24 * t, 174.0, 14.0
    # demo, in four parts of equal length: the camera orbits; Junior turns
    # towards the ball with the camera still; everything holds; the ball
    # rolls away while the camera follows it back.
    part, within = divmod(frame - 1, max(1, count // 4))
    u = within / max(1, count // 4 - 1)
    if part == 0:
        return 12 - 24 * u, 174.0, 14.0
    if part == 1:
        return -12.0, 174 - 20 * math.sin(math.pi * u), 14.0
    if part == 2:
        return -12.0, 174.0, 14.0
    return -12 + 24 * u, 174.0, 14 - 20 * u


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--shot", choices=["demo", "camera"], default="demo")
    parser.add_argument("--frames", type=int, default=48)
    parser.add_argument("--format", default="640 480", help="image width and height")
    args = parser.parse_args()

    text = SCENE.read_text()
    head, world = text.split("WorldBegin\n", 1)
    assert CAMERA in head and world.count(JUNIOR_TURN) == 2 and world.count(BALL) == 1, "desk_lamp.rib changed"
    head = head.replace('Display "desk_lamp.tif"', 'Display "desk_lamp_anim.####.tif"')
    head = head.replace("Format 640 480 1", f"Format {args.format} 1")
    options, camera_free = head.split(CAMERA)
    out = [f"##RenderMan RIB\n# Written by scripts/desk_lamp_animation.py --shot {args.shot} --frames {args.frames}\n"
           "# from desk_lamp.rib. Render from this folder: umbra render desk_lamp_anim.rib\n",
           "version 3.04\n"]
    options = "".join(line + "\n" for line in options.splitlines() if line and not line.startswith(("#", "version")))
    for frame in range(1, args.frames + 1):
        yaw, turn, ball = shot_pose(args.shot, frame, args.frames)
        body = world.replace(JUNIOR_TURN, f"Rotate {turn:.4g} 0 1 0").replace(BALL, f"Translate {ball:.4g} 8 18")
        out.append(f"FrameBegin {frame}\n{options}{camera_free}Translate 0 -12 165\nRotate -28 1 0 0\n"
                   f"Rotate {yaw:.4g} 0 1 0\nWorldBegin\n{body}FrameEnd\n")
    sys.stdout.write("".join(out))


if __name__ == "__main__":
    main()
