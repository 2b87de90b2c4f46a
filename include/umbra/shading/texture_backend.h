#pragma once
// Texture lookups and texture making, served by OpenImageIO's
// TextureSystem from a plugin (umbra_oiio.so) loaded on first use.
//
// Why a plugin: Debian's libOpenImageIO pulls in some 260 shared libraries,
// and the dynamic loader spends about 0.12 s on them at every process
// start, more than a whole small frame takes. Only frames that really read
// or make textures pay that, once, when the first lookup happens.

#include "umbra/util/math.h"

#include <string>
#include <vector>

namespace umbra::shading {

/// Options of one texture()/environment() call (RenderMan names).
struct TextureOptions {
    int firstChannel = 0;
    float sblur = 0, tblur = 0;    // "blur", "sblur", "tblur": extra filter width in texture coordinates
    float swidth = 1, twidth = 1;  // "width", "swidth", "twidth": multiply the filter width
    float fill = 0;                // value of channels the file lacks
};

/// What MakeTexture / MakeLatLongEnvironment / MakeCubeFaceEnvironment ask.
struct MakeTextureRequest {
    std::string kind;                 // "texture", "latlong" or "cubeface"
    std::vector<std::string> inputs;  // one image, or six cube faces (+x -x +y -y +z -z)
    std::string output;
    std::string swrap = "black", twrap = "black";  // "black", "periodic", "clamp"
    std::string filter = "gaussian";  // an OpenImageIO filter name (render/make_files.cpp maps RenderMan's)
    float swidth = 2, twidth = 2;
    /// Cube faces: the full field of view (degrees, >= 90) each face was
    /// rendered with. The faces are resampled into a lat-long map, stored
    /// and looked up as MakeLatLongEnvironment's are.
    float fov = 90;
};

/// The texture services; thread-safe. Implemented by the plugin.
class TextureBackend {
public:
    virtual ~TextureBackend() = default;
    /// Directories searched for texture files, ':'-separated.
    virtual void setSearchPath(const std::string& dirs) = 0;
    /// A filtered lookup at (s, t) over the footprint spanned by the two
    /// derivative vectors; `nchannels` results. False if the file is unreadable.
    virtual bool texture(const std::string& file, const TextureOptions& opt, float s, float t, float dsdx, float dtdx,
                         float dsdy, float dtdy, int nchannels, float* result) = 0;
    /// A filtered environment lookup in direction R.
    virtual bool environment(const std::string& file, const TextureOptions& opt, const Vec3& R, const Vec3& dRdx,
                             const Vec3& dRdy, int nchannels, float* result) = 0;
    /// textureinfo(): a string answer, or `count` numbers (int data converted).
    virtual bool textureInfoString(const std::string& file, const std::string& what, std::string* out) = 0;
    virtual bool textureInfoFloats(const std::string& file, const std::string& what, int count, float* out) = 0;
    /// Forgets what was read of `file` (its header and tiles), so the next
    /// lookup reads it again: for a file rewritten in place.
    virtual void invalidate(const std::string& file) = 0;
    /// Writes a tiled, mip-mapped texture OpenImageIO can read; false with
    /// the reason in `error`.
    virtual bool makeTexture(const MakeTextureRequest& request, std::string* error) = 0;
};

/// The backend, loading the plugin on the first call (thread-safe). Null,
/// with the reason in `error`, when the plugin cannot be loaded. The plugin
/// is looked for in $UMBRA_PLUGIN_PATH, beside the running executable, in
/// `<exe dir>/../lib/umbra` (an installed tree) and in the build's plugin
/// directory.
TextureBackend* textureBackend(std::string* error);

}  // namespace umbra::shading

/// The plugin's entry point (C linkage, found with dlsym).
extern "C" umbra::shading::TextureBackend* umbra_texture_backend();
