#pragma once
// The shading system: compiles RenderMan Shading Language shaders to
// bytecode, binds instance parameters from scene records, and runs
// displacement, surface (with its lights) and atmosphere shaders over a
// grid at a time. See docs/shading-language.md for the language.

#include "umbra/geometry/grid.h"
#include "umbra/scene/scene.h"
#include "umbra/shading/renderer_services.h"
#include "umbra/shading/texture_backend.h"
#include "umbra/util/error.h"

#include <map>
#include <memory>
#include <optional>
#include <mutex>
#include <string>
#include <vector>


namespace umbra::shading {

enum class ShaderKind { Surface, Light, Displacement, Volume, Imager };
const char* shaderKindName(ShaderKind k);

/// One shader parameter as declared, with its default when the default is
/// a constant (defaults that are expressions, such as
/// `point from = point "shader" (0,0,0)`, are evaluated when the shader runs).
struct ShaderParamInfo {
    std::string name;
    ValueType type = ValueType::Float;
    bool varying = false;
    bool output = false;
    int arraySize = 0;                 // 0: not an array
    bool constantDefault = false;
    std::vector<float> defaultFloats;  // when constantDefault
    std::vector<std::string> defaultStrings;
};

struct CompiledShader;  // bytecode and register layout (src/shading)

/// A compiled shader: immutable, shared by every instance and thread.
class Shader {
public:
    explicit Shader(std::shared_ptr<const CompiledShader> code);
    const std::string& name() const;
    ShaderKind kind() const;
    const std::vector<ShaderParamInfo>& params() const;
    /// The parameter called `name`, or nullptr.
    const ShaderParamInfo* param(const std::string& name) const;
    /// Human-readable bytecode listing (`umbra slc --listing`).
    std::string listing() const;
    /// Whether its results can change from frame to frame for the same
    /// geometry and parameters: it calls random() (seeded per frame),
    /// shadow() (stochastic, and maps made per frame) or option() (e.g.
    /// "FrameNumber").
    bool variesByFrame() const;
    /// Whether it reads the surface parameters u, v or the texture
    /// coordinates s, t (texture() without coordinates reads s and t):
    /// such a shader can tell how a surface was cut into grids, so
    /// geometry that changes the cut (subdivision blocks) must not.
    bool readsSurfaceParameters() const;
    const CompiledShader& code() const { return *m_code; }

private:
    std::shared_ptr<const CompiledShader> m_code;
};

/// A shader with instance parameter values bound from a scene record
/// (RenderMan's `Surface "plastic" "Kd" 0.8`): immutable once made.
class ShaderInstance {
public:
    const Shader& shader() const { return *m_shader; }
    const std::shared_ptr<const Shader>& shaderPtr() const { return m_shader; }
    /// The "shader" coordinate system: the transform current when the
    /// shader was named.
    const Mat4& worldFromShader() const { return m_worldFromShader; }
    /// Light category (the `__category` string parameter), empty if none.
    const std::string& category() const { return m_category; }

    /// A bound instance value (index into shader().params()); floats
    /// hold point/vector/normal values in "shader" space as given.
    struct Binding {
        int param = -1;
        std::vector<float> floats;
        std::vector<std::string> strings;
    };
    const std::vector<Binding>& bindings() const { return m_bindings; }

private:
    friend class ShadingSystem;
    std::shared_ptr<const Shader> m_shader;
    Mat4 m_worldFromShader;
    std::string m_category;
    std::vector<Binding> m_bindings;
};

/// The per-grid shading state: the renderer fills the global variables of
/// an nu x nv vertex grid (all in "current" = camera space), runs the
/// shaders, then reads Ci, Oi, P, N and output variables back.
/// Vertex (i, j) is at index j * uVertices + i, as in geometry::Grid.
class ShadingGrid {
public:
    /// Sizes every varying global for a uVertices x vVertices grid. Values
    /// are not cleared; fill what the primitive provides.
    void resize(int uVertices, int vVertices);
    /// Fills P, N, u, v, du, dv, s, t, Cs, Os, dPdu, dPdv, Ng from a diced
    /// grid already in camera space, and sets Ci = 0 and Oi = 1 (RI 3.2's
    /// values where a shader leaves them); `color`/`opacity` are the attribute
    /// values used when the grid has no Cs/Os; `eye` is E (camera space).
    /// Other grid variables are bound to shader parameters of the same name.
    void bind(const geometry::Grid& grid, const Color& color, const Color& opacity, bool perspective);

    int uVertices() const { return m_nu; }
    int vVertices() const { return m_nv; }
    int size() const { return m_nu * m_nv; }

    // Varying globals (one value per vertex).
    std::vector<Vec3> P, N, Ng, I, dPdu, dPdv, Cs, Os, Ci, Oi;
    std::vector<float> s, t, u, v;
    /// Imager grids only: the pixels' coverage (RenderMan's `alpha`), one
    /// per vertex; resize() leaves it alone and other grids leave it empty.
    std::vector<float> alpha;
    /// A moving grid's velocity in current space, one per vertex (RenderMan's
    /// `dPdtime`); empty for a still grid (then 0). resize() and bind()
    /// leave it alone: the renderer fills or clears it for every grid.
    std::vector<Vec3> dPdtime;
    /// A moving grid's path for shadow lookups: at each of its placement
    /// times (`pathTimes`, fractions of the shutter from 0 to 1), each
    /// vertex's offset from where it is at the opening, in current space
    /// with the camera held at the opening (so the world's motion, not the
    /// camera's): pathOffsets[key * size() + vertex]. Empty for a still
    /// grid; the renderer fills or clears both for every grid.
    std::vector<float> pathTimes;
    std::vector<Vec3> pathOffsets;
    // Uniform globals.
    float du = 0, dv = 0;
    Vec3 E{0, 0, 0};
    /// The shutter's opening (where a grid is shaded) and its length.
    float time = 0, dtime = 0;
    /// Camera-space z of the near and far clipping planes, for depth().
    float nearClip = 1e-10f, farClip = 1e30f;
    /// True when the primitive's orientation is left-handed, so that
    /// calculatenormal() flips Du(P)^Dv(P) to point outwards.
    bool flipNormals = false;
    /// Primitive variables bound by name to shader parameters (RenderMan
    /// binds primvars to parameters of the same name).
    const std::vector<geometry::GridVar>* primvars = nullptr;
    /// Identity of this grid for random() and stochastic shadow sampling.
    uint32_t seed = 0;
    /// The renderer's own pointer for RendererServices (primitive etc.).
    const void* renderState = nullptr;

    /// After shading: the values of an output parameter of the surface
    /// (or displacement) shader by name, `floats` per vertex (1 or 3).
    /// False if no such varying/uniform output exists.
    bool output(const std::string& name, std::vector<float>* values, int* floatsPerValue) const;

private:
    friend class ShadingSystem;
    friend struct Exec;
    int m_nu = 0, m_nv = 0;
    std::map<std::string, std::pair<int, std::vector<float>>> m_outputs;
};

/// What to run on one grid.
struct ShadeRequest {
    const ShaderInstance* displacement = nullptr;
    const ShaderInstance* surface = nullptr;       // null: defaultsurface behaviour
    const ShaderInstance* atmosphere = nullptr;
    std::vector<const ShaderInstance*> lights;
    /// Run the displacement shader only (depth passes): no surface, no
    /// default surface, no lights.
    bool displacementOnly = false;
    /// Names of output parameters to keep for AOVs (ShadingGrid::output).
    std::vector<std::string> outputs;
};

/// Compiles, caches and runs shaders. Thread-safe: compile()/find()/
/// instantiate() lock; shade() runs concurrently on many threads.
class ShadingSystem {
public:
    ShadingSystem(Diagnostics& diag, std::vector<std::string> searchPath);
    ~ShadingSystem();
    ShadingSystem(const ShadingSystem&) = delete;
    ShadingSystem& operator=(const ShadingSystem&) = delete;

    /// Compiles a shader source file (cached by path); null on error (the
    /// errors are reported to the Diagnostics).
    std::shared_ptr<const Shader> compile(const std::string& path);
    /// Finds `name` (or name.sl) on the search path and compiles it on first
    /// use; null (with an error at `loc`) if not found or invalid.
    std::shared_ptr<const Shader> find(const std::string& name, const FileLoc& loc = {});
    /// The source of shader `name` on the search path, if any: name.sl
    /// declaring it, else another .sl file declaring it. A name.sl that
    /// declares another shader is passed over, and said in `declaresOther`.
    std::optional<std::string> findFile(const std::string& name, std::string* declaresOther = nullptr) const;
    /// Compiles source text; `fileName` names it in messages. Not cached.
    std::shared_ptr<const Shader> compileSource(const std::string& source, const std::string& fileName);

    /// Binds a record's parameters to the named shader with RenderMan's
    /// type rules (a float promotes to a colour or point; point/vector/
    /// normal values are in "shader" space). Unknown or mistyped
    /// parameters are warned about once with record.loc. Null when the
    /// shader cannot be found/compiled or is not of kind `expected`.
    std::shared_ptr<const ShaderInstance> instantiate(const scene::ShaderRecord& record, ShaderKind expected);
    /// The same for an already compiled shader.
    std::shared_ptr<const ShaderInstance> instantiate(std::shared_ptr<const Shader> shader,
                                                      const scene::ShaderRecord& record);

    /// Directories searched by texture()/environment() (RIB "texture" searchpath).
    void setTextureSearchPath(const std::vector<std::string>& dirs);
    void setSearchPath(std::vector<std::string> dirs);

    /// Runs displacement, then surface (lights are run inside illuminance,
    /// once per grid each), then atmosphere. Without a surface, Ci = Cs
    /// shaded as defaultsurface and Oi = Os.
    void shade(ShadingGrid& grid, const ShadeRequest& request, RendererServices& services) const;
    /// Runs an imager shader over a grid of pixels: P is each pixel's
    /// raster position (x, y, 0), Ci/Oi its filtered colour and opacity and
    /// `alpha` its coverage (grid.alpha, one per vertex); the shader
    /// rewrites Ci, Oi and alpha in place.
    void shadeImager(ShadingGrid& grid, const ShaderInstance& imager, RendererServices& services) const;

    Diagnostics& diagnostics() const { return m_diag; }
    /// The texture backend (OpenImageIO in a plugin), loaded on first use
    /// with this system's texture search path; null, after one error, when
    /// the plugin cannot be loaded.
    TextureBackend* textures() const;

private:
    Diagnostics& m_diag;
    std::vector<std::string> m_searchPath;
    mutable std::mutex m_mutex;
    std::map<std::string, std::shared_ptr<const Shader>> m_byPath;
    std::map<std::string, std::shared_ptr<const Shader>> m_byName;
    std::shared_ptr<const Shader> m_default;
    std::string m_textureSearchPath;
    mutable std::once_flag m_texturesOnce;
    mutable TextureBackend* m_textures = nullptr;
};

/// `umbra slc [-I DIR] FILE.sl`: compiles one file, reporting errors;
/// #include looks beside the including file, then in `includePath`, then
/// in the standard shader directory. With a non-null `listing`, stores the
/// bytecode listing there. True on success.
bool compileFile(const std::string& path, const std::vector<std::string>& includePath, Diagnostics& diag,
                 std::string* listing);

}  // namespace umbra::shading
