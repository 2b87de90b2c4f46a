#!/bin/sh
# relocatable_test.sh CMAKE BUILD_DIR WORK_DIR SOURCE_DIR
#
# `cmake --install` into WORK_DIR/prefix, move the prefix to WORK_DIR/moved,
# then, from a directory holding no shaders, render a scene that uses the
# standard plastic and distantlight shaders, and make a texture (which
# loads the plugin). A scene naming a missing shader must report the
# moved tree's shader directory as the one searched, not the source tree's.
set -eu
cmake=$1 build=$2 work=$3 source=$4
unset UMBRA_SHADER_PATH UMBRA_TEXTURE_PATH UMBRA_PLUGIN_PATH || true
rm -rf "$work"
mkdir -p "$work/scene"
"$cmake" --install "$build" --prefix "$work/prefix" >"$work/install.log"
mv "$work/prefix" "$work/moved"
umbra=$work/moved/bin/umbra
for f in "$umbra" "$work/moved/lib/umbra/umbra_oiio.so" "$work/moved/share/umbra/shaders/plastic.sl"; do
  [ -f "$f" ] || { echo "not installed: $f"; exit 1; }
done

cd "$work/scene"
cat >plastic.rib <<'RIB'
Format 32 32 1
Display "plastic.tif" "file" "rgb"
Projection "perspective" "fov" 40
WorldBegin
  LightSource "distantlight" 1 "from" [0 0 0] "to" [0 0 1]
  Translate 0 0 5
  Surface "plastic"
  Sphere 1 -1 1 360
WorldEnd
RIB
"$umbra" render --quiet plastic.rib
[ -s plastic.tif ] || { echo "no image rendered"; exit 1; }
# The texture plugin is the moved tree's (glibc's loader names what it maps).
LD_DEBUG=files "$umbra" txmake plastic.tif plastic.tx 2>txmake.log
[ -s plastic.tx ] || { echo "no texture made"; cat txmake.log; exit 1; }
grep -q "file=$work/moved/lib/umbra/umbra_oiio.so .*generating link map" txmake.log ||
  { echo "the moved tree's plugin was not loaded:"; grep umbra_oiio txmake.log; exit 1; }

sed 's/"plastic"/"nosuchshader"/' plastic.rib >missing.rib
if "$umbra" render --quiet missing.rib 2>missing.log; then
  echo "a missing shader did not fail the render"; exit 1
fi
grep -q "cannot find shader 'nosuchshader'" missing.log || { cat missing.log; exit 1; }
grep -q "$work/moved/share/umbra/shaders" missing.log || { echo "moved shader dir not searched:"; cat missing.log; exit 1; }
if grep -q "$source/shaders_dsl" missing.log; then
  echo "the source tree's shaders were searched:"; cat missing.log; exit 1
fi
echo "ok"
