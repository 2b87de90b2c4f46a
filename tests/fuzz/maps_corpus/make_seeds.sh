#!/usr/bin/env bash
# Remakes the seeds of tests/fuzz/fuzz_maps from umbra's own output: two
# depth maps (min and second depth filters), a picture as TIFF and OpenEXR,
# and both made into mip-mapped textures by `umbra txmake`. Each seed is
# the file behind one byte choosing its extension (0 .shd, 1 .tx, 2 .tif,
# 3 .exr), as fuzz_maps.cpp reads it. Usage: make_seeds.sh path/to/umbra
set -euo pipefail
umbra=$(realpath "$1")
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
cat > maps.rib <<'RIB'
FrameBegin 1
Format 32 32 1
Projection "perspective" "fov" [40]
Display "min.shd" "shadow" "z"
Translate 0 0 4
WorldBegin
Sphere 1 -1 1 360
Translate 0.5 0 1
Sphere 0.4 -0.4 0.4 360
WorldEnd
FrameEnd
FrameBegin 2
Format 32 32 1
Projection "orthographic"
ScreenWindow -2 2 -2 2
Hider "hidden" "depthfilter" "second"
Display "second.shd" "shadow" "z"
Translate 0 0 4
WorldBegin
Sphere 1 -1 1 360
WorldEnd
FrameEnd
FrameBegin 3
Format 16 16 1
Projection "perspective" "fov" [40]
Display "picture.tif" "file" "rgba"
Display "+picture.exr" "openexr" "rgba"
Translate 0 0 4
WorldBegin
Color 1 0.5 0.2
Surface "constant"
Sphere 1.5 -1.5 1.5 360
WorldEnd
FrameEnd
RIB
"$umbra" render --quiet maps.rib
"$umbra" txmake picture.tif picture.tx
"$umbra" txmake picture.exr picture_tx.exr
seed() { (printf "\\x$1"; cat "$2") > "$here/$3"; }
seed 00 min.shd min_depth.shd.seed
seed 00 second.shd second_depth.shd.seed
seed 01 picture.tx mipmapped.tx.seed
seed 02 picture.tif plain.tif.seed
seed 03 picture.exr plain.exr.seed
seed 03 picture_tx.exr mipmapped.exr.seed
