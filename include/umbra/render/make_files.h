#pragma once
// The texture makers: MakeTexture, MakeLatLongEnvironment,
// MakeCubeFaceEnvironment and MakeShadow. The RIB requests (through
// Renderer::make) and the `umbra txmake` command both run makeFile, so the
// two write the same files.

#include "umbra/scene/scene.h"
#include "umbra/util/error.h"

namespace umbra::render {

/// Runs one Make* request: checks its arguments, reads the inputs and
/// writes `make.output` under a temporary name, moved into place when
/// complete. Errors are reported at `make.loc`, naming the file and what
/// was expected; false (and no output file) on any error.
///
///   MakeTexture             inputs {picture}, stringArgs {swrap, twrap, filter}, floatArgs {swidth, twidth}
///   MakeLatLongEnvironment  inputs {picture}, stringArgs {filter}, floatArgs {swidth, twidth}
///   MakeCubeFaceEnvironment inputs {px, nx, py, ny, pz, nz}, stringArgs {filter}, floatArgs {fov, swidth, twidth}
///   MakeShadow              inputs {zfile or OpenEXR depth image}
bool makeFile(const scene::MakeRecord& make, Diagnostics& diag);

/// The RenderMan filter names MakeTexture accepts ("box", "gaussian", ...),
/// ", "-separated, for messages and --help.
const char* makeFilterNames();

}  // namespace umbra::render
