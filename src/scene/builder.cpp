#include "umbra/scene/builder.h"

#include "umbra/util/frame_set.h"
#include "umbra/util/search_path.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace umbra::scene {

namespace {

const char* beginName(int kind) {
    static const char* k[] = {"FrameBegin",  "WorldBegin",  "AttributeBegin", "TransformBegin",
                              "SolidBegin",  "ObjectBegin", "MotionBegin",    "ResourceBegin"};
    return k[kind];
}
const char* endName(int kind) {
    static const char* k[] = {"FrameEnd", "WorldEnd", "AttributeEnd", "TransformEnd",
                              "SolidEnd", "ObjectEnd", "MotionEnd",   "ResourceEnd"};
    return k[kind];
}

/// How deep SolidBegin operations may nest (docs/rib.md, Limits).
constexpr int kMaxSolidNesting = 256;

/// How much the object definitions may hold together before an instance
/// inside a definition is refused (docs/rib.md, Limits): nested instances
/// multiply, and each piece is a copy.
constexpr size_t kMaxObjectBytes = size_t(256) << 20;

/// About the bytes a record holds, its arrays and parameters included.
size_t recordBytes(const PrimitiveRecord& r) {
    size_t n = sizeof r + r.floatArgs.size() * sizeof(float) + r.intArgs.size() * sizeof(int);
    for (const std::string& a : r.stringArgs) n += sizeof a + a.size();
    for (const auto& a : r.intArrays) n += sizeof a + a.size() * sizeof(int);
    for (const ri::Param& p : r.params.params()) {
        n += sizeof p + p.floats.size() * sizeof(float) + p.ints.size() * sizeof(int);
        for (const std::string& a : p.strings) n += sizeof a + a.size();
    }
    for (const PrimitiveRecord& shape : r.shapes) n += recordBytes(shape);
    return n;
}

/// The procedural primitives of RI spec 3.2 §5.7, and the strings each
/// needs at least: the archive; the program (with its command line) and
/// the data block written to it; the DSO and the data block it converts.
struct ProceduralKind {
    const char* name;
    size_t strings;
    const char* what;
};
constexpr ProceduralKind kProceduralKinds[] = {
    {"DelayedReadArchive", 1, "[\"archive.rib\"]"},
    {"RunProgram", 2, "[\"program args\" \"datablock\"]"},
    {"DynamicLoad", 2, "[\"dso\" \"datablock\"]"},
};

/// Named objects other renderers draw for `Geometry "name"` (PRMan,
/// Aqsis, Pixie): umbra draws the teapot and warns for the others.
constexpr const char* kOtherGeometryNames[] = {"bunny", "cube", "sphere", "torus", "envsphere"};

/// The numeric settings of Option (and Attribute) "umbra": the range each
/// must lie in. Out of range, they would make a depth pass of no pixels, or
/// one no machine has the memory for (docs/shadows.md lists them).
struct UmbraNumber {
    const char* name;
    double lo, hi;
    const char* what;
};
constexpr UmbraNumber kUmbraNumbers[] = {
    {"shadowmapsize", 1, 16384, "an integer from 1 to 16384"},
    {"tilecachemb", 1, 1 << 20, "an integer from 1 to 1048576"},
    {"depthlayers", 1, 2, "1 or 2"},
    {"depthshadingrate", 0, 1e6, "a rate of 0 (the surfaces' own) or more"},
    {"dualoffset", 0, 1e6, "an offset of 0 or more"},
    {"reusemaps", 0, 1, "0 (render every automatic map) or 1"},
    {"patchblock", 0, 64, "an integer from 0 to 64 (patches along a block's side; 0 or 1: patch by patch)"},
};

/// Whether `p`, a parameter of Option or Attribute "umbra", holds a value
/// in its range (parameters not in the table are not checked here);
/// reports the error at the parameter when not.
bool umbraValueValid(const char* request, const ri::Param& p, Diagnostics& diag) {
    for (const UmbraNumber& n : kUmbraNumbers) {
        if (p.decl.name != n.name) continue;
        double v = !p.ints.empty() ? double(p.ints[0]) : !p.floats.empty() ? double(p.floats[0]) : std::nan("");
        if (v >= n.lo && v <= n.hi) return true;
        diag.error(p.loc, "{}: umbra \"{}\" expects {}, got {}", request, n.name, n.what,
                   std::isnan(v) ? std::string("no number") : fmt::format("{}", v));
        return false;
    }
    return true;
}

}  // namespace

Builder::Builder(SceneSink& sink, Diagnostics& diag) : m_sink(sink), m_diag(diag) {
    m_state.attrs = std::make_shared<Attributes>();
}

Builder::~Builder() = default;

void Builder::setDefaultSearchPath(const std::string& kind, const std::string& path) {
    m_defaultSearchPaths[kind] = path;
}

void Builder::setSearchPath(const std::string& kind, const std::string& spec) {
    m_options.searchPaths[kind] = expandSearchPath(kind, spec);
}

void Builder::unhandled(std::string_view request, const FileLoc& loc) {
    m_diag.warningOnce("unhandled:" + std::string(request), loc, "{}: not handled by the scene builder", request);
}

std::vector<std::string> Builder::archiveSearchPath() const {
    auto it = m_options.searchPaths.find("archive");
    if (it == m_options.searchPaths.end() || it->second.empty()) it = m_options.searchPaths.find("resource");
    if (it == m_options.searchPaths.end()) return {};
    return splitSearchPath(it->second);
}

void Builder::unsupported(const std::string& key, const FileLoc& loc, const std::string& what) {
    m_diag.warningOnce("unsupported:" + key, loc, "{}", what);
}

Attributes& Builder::mutableAttributes() {
    // Copy on write: records and saved states share the attributes object.
    if (m_state.attrs.use_count() > 1) m_state.attrs = std::make_shared<Attributes>(*m_state.attrs);
    return *m_state.attrs;
}

bool Builder::currentIsLeft(const Mat4& transform) const {
    // Camera space is left-handed; each mirroring transform flips.
    float det = transform.det3();
    if (m_world) det *= m_options.cameraFromWorld.det3();
    return det >= 0;
}

std::shared_ptr<ShaderRecord> Builder::makeShader(const std::string& name, ri::ParamList params,
                                                  const FileLoc& loc) const {
    auto s = std::make_shared<ShaderRecord>();
    s->name = name;
    s->params = std::move(params);
    s->worldFromShader = m_state.transform;
    s->loc = loc;
    return s;
}

bool Builder::optionsAllowed(const char* request, const FileLoc& loc) {
    if (!m_world) return true;
    m_diag.error(loc, "{}: options cannot change inside WorldBegin/WorldEnd (ignored)", request);
    return false;
}

bool Builder::requireWorld(const std::string& request, const FileLoc& loc) {
    if (m_world || !m_objectHandle.empty()) return true;
    m_diag.error(loc, "{}: only allowed inside WorldBegin/WorldEnd (ignored)", request);
    return false;
}

bool Builder::skipMotionSample(const char* request, const FileLoc& loc) {
    if (!m_motion || m_blocks.empty() || m_blocks.back().kind != Block::Motion) return false;
    if (++m_motion->requests == 1) return false;
    if (!m_motion->warnedUnblurred) {
        m_motion->warnedUnblurred = true;
        m_diag.warning(loc, "{}: not blurred in a motion block (umbra blurs transforms and primitives); the "
                       "block's first request is used", request);
    }
    return true;
}

void Builder::setTransform(const Mat4& m) {
    m_state.transform = m;
    m_state.motion.reset();
}

void Builder::push(Block kind, const FileLoc& loc) {
    OpenBlock b;
    b.kind = kind;
    b.loc = loc;
    b.saved = m_state;
    m_blocks.push_back(std::move(b));
}

bool Builder::pop(Block kind, const char* request, const FileLoc& loc, OpenBlock* out) {
    auto it = std::find_if(m_blocks.rbegin(), m_blocks.rend(), [&](const OpenBlock& b) { return b.kind == kind; });
    if (it == m_blocks.rend()) {
        m_diag.error(loc, "{}: no matching {} (ignored)", request, beginName(int(kind)));
        return false;
    }
    if (it != m_blocks.rbegin()) {
        const OpenBlock& inner = m_blocks.back();
        if (kind != Block::World && kind != Block::Frame) {
            m_diag.error(loc, "{}: expected {} first, to close the {} at {} (ignored)", request,
                         endName(int(inner.kind)), beginName(int(inner.kind)), inner.loc.str());
            return false;
        }
        // Close what was left open inside the world or frame.
        const size_t first = size_t(m_blocks.rend() - it);
        reportOpenBlocks(first, request, loc);
        while (m_blocks.back().kind != kind) {
            const OpenBlock& b = m_blocks.back();
            if (b.kind == Block::Object) m_objectHandle.clear();
            if (b.kind == Block::World) m_world.reset();
            // An open motion block dies with its world: its shapes would
            // otherwise reach a later MotionEnd with no world to go to.
            if (b.kind == Block::Motion) m_motion.reset();
            m_blocks.pop_back();
        }
    }
    *out = std::move(m_blocks.back());
    m_blocks.pop_back();
    return true;
}

void Builder::reportOpenBlocks(size_t first, const char* request, const FileLoc& loc) {
    // Innermost first; 1e5 unclosed AttributeBegins give a few lines, not 1e5.
    size_t listed = 0;
    for (size_t k = m_blocks.size(); k-- > first;) {
        const OpenBlock& b = m_blocks[k];
        if (listed == size_t(kMaxListedOpenBlocks)) {
            const size_t rest = k + 1 - first;
            const OpenBlock& outer = m_blocks[first];
            if (request)
                m_diag.error(loc, "{}: ... and {} more open blocks, closed here (the outermost is the {} at {})",
                             request, rest, beginName(int(outer.kind)), outer.loc.str());
            else
                m_diag.error(outer.loc, "{}: ... and {} more blocks with no matching end before the end of the "
                             "input (the outermost is this one)", beginName(int(outer.kind)), rest);
            return;
        }
        ++listed;
        if (request)
            m_diag.error(loc, "{}: the {} at {} is still open (closed here)", request, beginName(int(b.kind)),
                         b.loc.str());
        else
            m_diag.error(b.loc, "{}: no matching {} before the end of the input", beginName(int(b.kind)),
                         endName(int(b.kind)));
    }
}

void Builder::endOfInput(const FileLoc& loc) {
    reportOpenBlocks(0, nullptr, loc);
    m_blocks.clear();
    // A procedural's RIB ends inside the world it expands into.
    if (m_procedural) return;
    m_world.reset();
    m_objectHandle.clear();
}

void Builder::version(float v, const FileLoc& loc) {}
void Builder::declare(const ri::ParamDecl& decl, const FileLoc& loc) {
    // Displays name declared output variables bare: `Declare "mask"
    // "varying float"`, then `Display "+m.tif" "file" "mask"`.
    m_declarations[decl.name] = decl;
}
bool Builder::readArchive(const std::string& resolvedPath, const FileLoc& loc) {
    // The nesting limit bounds the depth, not the work: archives that each
    // read the next twice, 30 deep, would read 2^30 files. Each frame may
    // make m_options.archiveReads reads; one error, then the rest of the
    // frame's ReadArchive requests are skipped.
    if (m_archiveReads < m_options.archiveReads) {
        ++m_archiveReads;
        return true;
    }
    if (!m_archiveBudgetReported)
        m_diag.error(loc, "ReadArchive: more than {} archive reads in one frame; this and the frame's further "
                     "ReadArchive requests are skipped (raise Option \"limits\" \"archivereads\" if the scene "
                     "needs more)", m_options.archiveReads);
    m_archiveBudgetReported = true;
    return false;
}

void Builder::errorHandler(const std::string& name, const FileLoc& loc) {
    if (name == "print")
        m_diag.setPolicy(Diagnostics::Policy::Print);
    else if (name == "ignore")
        m_diag.setPolicy(Diagnostics::Policy::Ignore);
    else if (name == "abort")
        m_diag.setPolicy(Diagnostics::Policy::Abort);
    else
        m_diag.error(loc, "ErrorHandler: unknown handler \"{}\" (expected \"print\", \"ignore\" or \"abort\")", name);
}

void Builder::frameBegin(int frame, const FileLoc& loc) {
    if (m_world) {
        m_diag.error(loc, "FrameBegin: not allowed inside WorldBegin/WorldEnd (ignored)");
        return;
    }
    for (const OpenBlock& b : m_blocks)
        if (b.kind == Block::Frame) {
            m_diag.error(loc, "FrameBegin: frames cannot nest (the frame begun at {} is still open)", b.loc.str());
            return;
        }
    push(Block::Frame, loc);
    m_archiveReads = 0;
    m_archiveBudgetReported = false;
    m_blocks.back().savedOptions = std::make_shared<Options>(m_options);
    m_blocks.back().savedSpaces = std::make_shared<std::map<std::string, Mat4>>(m_cameraSpaces);
    m_frame = frame;
    m_options.loc = loc;
    m_sink.frameBegin(frame, loc);
}

void Builder::frameEnd(const FileLoc& loc) {
    OpenBlock b;
    if (!pop(Block::Frame, "FrameEnd", loc, &b)) return;
    if (m_world) {
        m_world.reset();  // already reported as left open by pop()
        m_lightHandles.clear();
    }
    m_options = *b.savedOptions;
    m_cameraSpaces = *b.savedSpaces;
    m_namedCameras.clear();
    m_state = b.saved;
    m_frame = m_defaultFrame;
    m_objectHandle.clear();
    m_preWorldLights.clear();
    m_sink.frameEnd(loc);
}

void Builder::worldBegin(const FileLoc& loc) {
    if (m_world) {
        m_diag.error(loc, "WorldBegin: already inside the world begun at {} (ignored)", m_world->loc.str());
        return;
    }
    if (!m_objectHandle.empty()) {
        m_diag.error(loc, "WorldBegin: not allowed inside ObjectBegin/ObjectEnd (ignored)");
        return;
    }
    // Blocks must nest (RI Spec 3.2): a world inside an attribute or
    // transform block is refused by Pixie and Aqsis. The intent is plain,
    // so the world is rendered, and the user told.
    for (const OpenBlock& b : m_blocks)
        if (b.kind != Block::Frame && b.kind != Block::Resource) {
            m_diag.warning(loc, "WorldBegin: inside the {} block opened at {} (blocks must nest; Pixie and Aqsis "
                                "refuse this world, umbra renders it)", beginName(int(b.kind)), b.loc.str());
            break;
        }
    push(Block::World, loc);
    m_options.cameraFromWorld = m_state.transform;
    m_options.cameraMotion = m_state.motion;
    if (!m_options.loc.file) m_options.loc = loc;
    m_world = std::make_unique<WorldRecord>();
    m_world->frameNumber = m_frame;
    m_world->options = m_options;
    fitFrameAspectRatio(m_world->options);
    if (m_world->options.displays.empty()) {
        // A RIB with no Display (modellers' exports, a bare world block)
        // rendered to nothing at all. The spec leaves the default to the
        // renderer: PRMan and Aqsis write "ri.pic" (a TIFF), Pixie ri.tif.
        DisplayRecord d;
        d.name = "ri.pic";
        d.driver = "file";
        d.mode = "rgba";
        d.loc = loc;
        d.implicitDefault = true;  // the renderer says so when it writes it
        m_world->options.displays.push_back(std::move(d));
    }
    // Display "out.####.tif" in frame 12 writes out.0012.tif (also %04d).
    if (m_frame >= 0)
        for (DisplayRecord& d : m_world->options.displays)
            if (hasFramePattern(d.name)) {
                d.pattern = d.name;
                d.name = expandFramePattern(d.name, m_frame);
            }
    m_world->loc = loc;
    bool ok = true;
    Mat4 worldFromCamera = m_options.cameraFromWorld.inverse(&ok);
    if (!ok) m_diag.error(loc, "WorldBegin: the camera transform is singular");
    m_world->coordinateSystems["world"] = Mat4::identity();
    m_world->coordinateSystems["camera"] = worldFromCamera;
    for (const auto& [name, cameraFromNamed] : m_cameraSpaces)
        m_world->coordinateSystems[name] = worldFromCamera * cameraFromNamed;
    for (const auto& [name, namedCameraFromWorld] : m_namedCameras) {
        bool invertible = true;
        Mat4 worldFromNamed = namedCameraFromWorld.inverse(&invertible);
        if (invertible) m_world->coordinateSystems[name] = worldFromNamed;
    }
    m_lightHandles.clear();
    setTransform(Mat4::identity());
    for (const PreWorldLight& l : m_preWorldLights) {
        const size_t first = m_world->lights.size();
        if (l.area)
            areaLightSource(l.name, l.handle, l.params, l.loc);
        else
            lightSource(l.name, l.handle, l.params, l.loc);
        if (m_world->lights.size() > first) {
            m_world->lights.back().shader.worldFromShader = worldFromCamera * l.cameraFromShader;
            if (!l.on) illuminate(l.handle, false, l.loc);
        }
    }
}

void Builder::worldEnd(const FileLoc& loc) {
    OpenBlock b;
    if (!m_world) {
        m_diag.error(loc, "WorldEnd: no matching WorldBegin (ignored)");
        return;
    }
    if (!pop(Block::World, "WorldEnd", loc, &b)) return;
    std::unique_ptr<WorldRecord> world = std::move(m_world);
    m_lightHandles.clear();
    m_state = b.saved;
    m_objectHandle.clear();
    if (!world) return;
    // A run's arrays grew by doubling; the render holds them as long as
    // every primitive made from them.
    for (PrimitiveRecord& r : world->primitives)
        if (r.type == "Polygon" && !r.intArrays.empty()) {
            r.intArrays[0].shrink_to_fit();
            r.params.findMutable("P")->floats.shrink_to_fit();
        }
    m_sink.renderWorld(*world);
}

void Builder::attributeBegin(const FileLoc& loc) { push(Block::Attribute, loc); }

void Builder::attributeEnd(const FileLoc& loc) {
    OpenBlock b;
    if (pop(Block::Attribute, "AttributeEnd", loc, &b)) m_state = b.saved;
}

void Builder::transformBegin(const FileLoc& loc) { push(Block::Transform, loc); }

void Builder::transformEnd(const FileLoc& loc) {
    OpenBlock b;
    if (pop(Block::Transform, "TransformEnd", loc, &b)) {
        m_state.transform = b.saved.transform;
        m_state.motion = b.saved.motion;
    }
}

void Builder::solidBegin(const std::string& operation, const FileLoc& loc) {
    if (operation != "primitive" && operation != "union" && operation != "intersection" &&
        operation != "difference") {
        m_diag.error(loc, "SolidBegin: unknown operation \"{}\" (expected \"primitive\", \"union\", "
                     "\"intersection\" or \"difference\")", operation);
    }
    push(Block::Solid, loc);
    mutableAttributes().solid = operation;
    const bool known = operation == "primitive" || operation == "union" || operation == "intersection" ||
                       operation == "difference";
    if (!known || !m_world) return;
    if (!m_objectHandle.empty()) {
        if (operation != "primitive")
            unsupported("csg-object", loc, "SolidBegin: CSG inside ObjectBegin is not supported; the object's "
                        "solids are drawn as if \"union\"");
        return;
    }
    // A top-level primitive solid is ordinary geometry; one inside another
    // is part of it (a primitive solid holds only surfaces).
    if (m_state.solid < 0 && operation == "primitive") return;
    if (m_state.solid >= 0 && m_world->solids[size_t(m_state.solid)].operation == "primitive") {
        m_diag.warning(loc, "SolidBegin: \"{}\" inside the \"primitive\" solid begun at {} (expected only "
                       "geometry there; its surfaces are part of that solid)", operation,
                       m_world->solids[size_t(m_state.solid)].loc.str());
        return;
    }
    // Each hit a sample resolves walks up its leaf's ancestors: a bounded
    // depth keeps a pathological file from costing depth x hits per sample.
    int depth = 0;
    for (int n = m_state.solid; n >= 0; n = m_world->solids[size_t(n)].parent) ++depth;
    if (depth >= kMaxSolidNesting) {
        m_diag.error(loc, "SolidBegin: CSG nested deeper than {} solids (its surfaces are part of the enclosing "
                     "solid)", kMaxSolidNesting);
        return;
    }
    m_world->solids.push_back(SolidRecord{operation, m_state.solid, loc});
    m_state.solid = int(m_world->solids.size()) - 1;
}

int Builder::solidLeaf(const FileLoc& loc) {
    if (m_state.solid < 0 || !m_world) return -1;
    if (m_world->solids[size_t(m_state.solid)].operation == "primitive") return m_state.solid;
    m_world->solids.push_back(SolidRecord{"primitive", m_state.solid, loc});
    return int(m_world->solids.size()) - 1;
}

void Builder::solidEnd(const FileLoc& loc) {
    OpenBlock b;
    if (pop(Block::Solid, "SolidEnd", loc, &b)) m_state = b.saved;
}

void Builder::objectBegin(const std::string& handle, const FileLoc& loc) {
    if (!m_objectHandle.empty()) {
        m_diag.error(loc, "ObjectBegin: object definitions cannot nest (ignored)");
        return;
    }
    push(Block::Object, loc);
    m_objectHandle = handle;
    ObjectDefinition& def = m_objects[handle];
    m_objectBytes -= def.bytes;
    def = {};
    m_objectAttributesAtBegin = m_state.attrs;
    bool ok = true;
    m_objectFromCurrentAtBegin = m_state.transform.inverse(&ok);
    if (!ok) m_diag.error(loc, "ObjectBegin: the current transform is singular");
}

void Builder::objectEnd(const FileLoc& loc) {
    OpenBlock b;
    if (!pop(Block::Object, "ObjectEnd", loc, &b)) return;
    m_state = b.saved;
    m_objectHandle.clear();
}

void Builder::objectInstance(const std::string& handle, const FileLoc& loc) {
    if (!requireWorld("ObjectInstance", loc)) return;
    auto it = m_objects.find(handle);
    if (it == m_objects.end()) {
        m_diag.error(loc, "ObjectInstance: unknown object \"{}\" (expected the handle of an ObjectBegin)", handle);
        return;
    }
    // An instance inside a definition (PRMan, Pixie and Aqsis draw it) puts
    // copies of the pieces into the object being defined, placed and
    // attributed as they are here; its own instances place them again.
    const bool nested = !m_objectHandle.empty();
    if (nested && handle == m_objectHandle) {
        m_diag.error(loc, "ObjectInstance: object \"{}\" inside its own definition (ignored)", handle);
        return;
    }
    if (nested && m_objectBytes + it->second.bytes > kMaxObjectBytes) {
        // Nested instances multiply: a few lines of RIB could ask for more
        // copies than memory holds.
        m_diag.error(loc, "ObjectInstance: the object definitions would hold more than {} MiB (instances nested "
                     "too deep?); this instance in \"{}\" is ignored", kMaxObjectBytes >> 20, m_objectHandle);
        return;
    }
    if (skipMotionSample("ObjectInstance", loc)) return;
    // Pieces share attributes: the instance's where the definition set
    // none, else one merge per distinct state inside the definition.
    std::map<const Attributes*, std::shared_ptr<const Attributes>> merged;
    const int leaf = nested ? -1 : solidLeaf(loc);  // an instance is one solid
    for (const ObjectPrim& op : it->second.pieces) {
        PrimitiveRecord r = op.record;
        r.solid = leaf;
        r.worldFromObject = m_state.transform * op.objectFromPrim;
        // The instance's motion, then the piece's own inside the definition
        // (a motion block there moves every instance alike).
        if (m_state.motion || op.objectFromPrimMotion) {
            auto moving = std::make_shared<MotionTransform>(m_state.motion ? *m_state.motion
                                                                           : MotionTransform(m_state.transform));
            if (op.objectFromPrimMotion)
                moving->postMultiply(*op.objectFromPrimMotion);
            else
                moving->postMultiply(op.objectFromPrim);
            r.worldFromObjectMotion = std::move(moving);
        }
        if (op.record.attributes == op.atBegin) {
            r.attributes = m_state.attrs;
        } else {
            auto& a = merged[op.record.attributes.get()];
            if (!a) a = std::make_shared<const Attributes>(instanceAttributes(*m_state.attrs, *op.atBegin, *op.record.attributes));
            r.attributes = a;
        }
        if (nested)
            emitPrimitive(std::move(r));  // relative to the object being defined
        else
            m_world->primitives.push_back(std::move(r));
    }
}

void Builder::motionBegin(const std::vector<float>& times, const FileLoc& loc) {
    if (m_motion) {
        m_diag.error(loc, "MotionBegin: already inside the motion block begun at {} (motion blocks do not nest; "
                     "ignored)", m_motion->loc.str());
        return;
    }
    bool ascending = !times.empty();
    for (size_t k = 1; k < times.size(); ++k) ascending &= times[k] > times[k - 1];
    push(Block::Motion, loc);
    m_motion = std::make_unique<MotionBlock>();
    m_motion->loc = loc;
    if (!ascending) {
        m_diag.error(loc, "MotionBegin: expected one or more times in increasing order (the block is not blurred; "
                     "its first request is used)");
        return;
    }
    m_motion->times = times;
}

void Builder::motionEnd(const FileLoc& loc) {
    OpenBlock b;
    if (!m_motion) {
        pop(Block::Motion, "MotionEnd", loc, &b);  // reports the missing MotionBegin
        return;
    }
    pop(Block::Motion, "MotionEnd", loc, &b);
    std::unique_ptr<MotionBlock> block = std::move(m_motion);
    const size_t n = block->times.size();
    auto countMismatch = [&](const char* what, size_t got) {
        m_diag.error(loc, "MotionEnd: the block begun at {} has {} times but {} {} (RI spec: one request per "
                     "time); {}", block->loc.str(), n, got, what,
                     got > n ? "the extra ones are ignored" : "the last is held for the missing times");
    };
    if (!block->transforms.empty()) {
        std::vector<TransformRequest> keys = block->transforms;
        if (keys.size() != n && n > 0) countMismatch("transforms", keys.size());
        for (const TransformRequest& k : keys)
            if (k.kind != keys[0].kind) {
                m_diag.warning(block->loc, "MotionBegin: the block's transforms are not all the same request (RI "
                               "spec: one kind a block); blurred between their matrices");
                break;
            }
        keys.resize(std::max<size_t>(n, 1), keys.back());
        auto moving = std::make_shared<MotionTransform>(block->absolute ? MotionTransform()
                                                        : m_state.motion ? *m_state.motion
                                                                         : MotionTransform(m_state.transform));
        moving->postMultiplyMoving(block->times, keys);
        const Options& o = m_world ? m_world->options : m_options;
        const float open = o.shutter[0] + o.shutterOffset;
        m_state.transform = moving->at(open);
        m_state.motion = moving->moving() ? std::move(moving) : nullptr;
    }
    if (!block->shapes.empty()) {
        std::vector<PrimitiveRecord>& shapes = block->shapes;
        if (shapes.size() != n && n > 0) countMismatch("primitives", shapes.size());
        PrimitiveRecord first = std::move(shapes[0]);
        // Every shape must be the same primitive with other values.
        bool same = true;
        for (size_t k = 1; k < shapes.size() && k < n && same; ++k) {
            const PrimitiveRecord& r = shapes[k];
            // A Polygon's (and a Points', a Curves') topology is also its
            // number of positions.
            auto positions = [](const PrimitiveRecord& x) {
                size_t count = 0;
                for (const char* name : {"P", "Pw", "Pz"})
                    if (const ri::Param* p = x.params.find(name)) count += p->floats.size();
                return count;
            };
            same = r.type == first.type && r.intArgs == first.intArgs && r.intArrays == first.intArrays &&
                   r.stringArgs == first.stringArgs && r.floatArgs.size() == first.floatArgs.size() &&
                   positions(r) == positions(first);
            if (!same)
                m_diag.error(r.loc, "{}: a motion block's primitives must have the same type and topology as its "
                             "first ({} at {}); the block renders the first, unblurred", r.type, first.type,
                             first.loc.str());
        }
        if (same && n > 1) {
            // Shading happens once, at the opening (as in PRMan and Aqsis):
            // a colour or other variable that changes between the keys is
            // the first key's. Said once, where it changes.
            for (size_t k = 1; k < shapes.size() && k < n; ++k)
                for (const ri::Param& p : shapes[k].params.params()) {
                    static const char* kMoved[] = {"P", "Pw", "Pz", "N", "width", "constantwidth"};
                    if (std::any_of(std::begin(kMoved), std::end(kMoved),
                                    [&](const char* m) { return p.decl.name == m; }))
                        continue;
                    const ri::Param* q = first.params.find(p.decl.name);
                    if (q && q->floats == p.floats && q->ints == p.ints && q->strings == p.strings) continue;
                    m_diag.warningOnce("motion:primvar:" + p.decl.name, shapes[k].loc,
                                       "{}: \"{}\" differs between the motion block's keys; the first key's is used "
                                       "(umbra shades once, at the shutter's opening)", shapes[k].type, p.decl.name);
                }
            for (size_t k = 1; k < n; ++k) first.shapes.push_back(k < shapes.size() ? shapes[k] : shapes.back());
            for (PrimitiveRecord& r : first.shapes) r.shapes.clear();
            first.shapeTimes = block->times;
        }
        emitPrimitive(std::move(first));
    }
}

void Builder::concat(const TransformRequest& request, bool absolute) {
    const Mat4& m = request.matrix;
    if (m_motion && !m_blocks.empty() && m_blocks.back().kind == Block::Motion) {
        ++m_motion->requests;
        if (!m_motion->shapes.empty()) {
            m_diag.warningOnce("motion:mixed", m_motion->loc, "MotionBegin: a block mixing primitives and "
                               "transforms blurs the primitives only");
            return;
        }
        if (!m_motion->times.empty()) {
            m_motion->transforms.push_back(request);
            m_motion->absolute |= absolute;
            return;
        }
        if (m_motion->requests > 1) return;  // a malformed block: its first request only
    }
    if (absolute) {
        setTransform(m);
        return;
    }
    m_state.transform = m_state.transform * m;
    if (m_state.motion) {
        auto moved = std::make_shared<MotionTransform>(*m_state.motion);
        moved->postMultiply(m);
        m_state.motion = std::move(moved);
    }
}

void Builder::identity(const FileLoc& loc) { concat(Mat4::identity(), true); }

void Builder::transform(const Mat4& m, const FileLoc& loc) { concat(m, true); }

void Builder::concatTransform(const Mat4& m, const FileLoc& loc) { concat(m); }
void Builder::translate(const Vec3& d, const FileLoc& loc) {
    concat({TransformRequest::Kind::Translate, {d.x, d.y, d.z}, Mat4::translate(d)});
}

void Builder::rotate(float angleDeg, const Vec3& axis, const FileLoc& loc) {
    if (length(axis) == 0) {
        m_diag.error(loc, "Rotate: the axis must not be (0, 0, 0)");
        return;
    }
    concat({TransformRequest::Kind::Rotate, {angleDeg, axis.x, axis.y, axis.z}, Mat4::rotate(angleDeg, axis)});
}

void Builder::scale(const Vec3& s, const FileLoc& loc) {
    concat({TransformRequest::Kind::Scale, {s.x, s.y, s.z}, Mat4::scale(s)});
}

void Builder::skew(float angleDeg, const Vec3& d1, const Vec3& d2, const FileLoc& loc) {
    Mat4 m;
    if (!skewMatrix(angleDeg, d1, d2, &m)) {
        m_diag.error(loc, "Skew: the vectors must not be parallel and the skewed vector must stay within 90 degrees "
                     "of its perpendicular (ignored)");
        return;
    }
    concat({TransformRequest::Kind::Skew, {angleDeg, d1.x, d1.y, d1.z, d2.x, d2.y, d2.z}, m});
}

void Builder::perspective(float fovDeg, const FileLoc& loc) {
    if (!(fovDeg > 0 && fovDeg < 180)) {
        m_diag.error(loc, "Perspective: fov must be between 0 and 180 degrees, got {}", fovDeg);
        return;
    }
    if (!m_world) {
        // Before WorldBegin, Perspective describes the camera projection.
        m_options.projection = Projection::Perspective;
        m_options.fov = fovDeg;
        return;
    }
    // In the world: concatenate the projective matrix x/(z tan), y/(z tan),
    // with w = z and z' = (z - 1)/z so that it stays invertible.
    float t = std::tan(radians(fovDeg) / 2);
    Mat4 m;
    m.m[0][0] = 1 / t;
    m.m[1][1] = 1 / t;
    m.m[2][2] = 1;
    m.m[2][3] = -1;
    m.m[3][2] = 1;
    m.m[3][3] = 0;
    concat(m);
}

void Builder::coordinateSystem(const std::string& name, const FileLoc& loc) {
    if (m_world)
        m_world->coordinateSystems[name] = m_state.transform;
    else
        m_cameraSpaces[name] = m_state.transform;
}

void Builder::scopedCoordinateSystem(const std::string& name, const FileLoc& loc) {
    // PRMan's: a CoordinateSystem that AttributeEnd forgets, the name's
    // earlier meaning back in force (umbra kept it for the frame). Held in
    // the attributes, so shaders of the primitives inside see it too.
    if (!m_world) {
        coordinateSystem(name, loc);  // the camera's: the frame's own
        return;
    }
    mutableAttributes().scopedSpaces[name] = m_state.transform;
}

void Builder::camera(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    // RenderMan 14: names the camera the options describe so far. umbra
    // renders one camera; the name is that camera's coordinate system.
    if (!optionsAllowed("Camera", loc)) return;
    m_namedCameras[name] = m_state.transform;
    // PRMan's way of shaping the shutter: Camera "world" "float[2] shutteropening" [a b].
    for (const ri::Param& p : params.params())
        if (p.decl.name == "shutteropening") setShutterOpening("Camera", p);
}

void Builder::setShutterOpening(const char* request, const ri::Param& p) {
    const float a = p.floats.size() == 2 ? p.floats[0] : -1, b = p.floats.size() == 2 ? p.floats[1] : -1;
    if (!(a >= 0 && a <= b && b <= 1)) {
        m_diag.error(p.loc, "{} \"{}\" expects two fractions 0 <= a <= b <= 1 of the shutter interval (ignored)",
                     request, p.decl.name);
        return;
    }
    m_options.shutterOpening[0] = a;
    m_options.shutterOpening[1] = b;
}

void Builder::resource(const std::string& handle, const std::string& type, ri::ParamList params,
                       const FileLoc& loc) {
    if (type != "attributes") {
        unsupported("resource:" + type, loc,
                    fmt::format("Resource: type \"{}\" is not supported (only \"attributes\"; ignored)", type));
        return;
    }
    const std::string op = params.getString("operation", "");
    const std::string subset = params.getString("subset", "all");
    if (op == "save") {
        m_resources[handle] = m_state;
        return;
    }
    if (op != "restore") {
        m_diag.error(loc, "Resource: \"operation\" must be \"save\" or \"restore\", got \"{}\" (ignored)", op);
        return;
    }
    auto it = m_resources.find(handle);
    if (it == m_resources.end()) {
        m_diag.error(loc, "Resource: no attributes saved as \"{}\" (expected a Resource \"{}\" \"attributes\" "
                     "\"operation\" \"save\" first; ignored)", handle, handle);
        return;
    }
    const State& saved = it->second;
    if (subset == "all") {
        m_state = saved;
        return;
    }
    // The subsets of PRMan's attribute state; the transform belongs to "all".
    const Attributes& from = *saved.attrs;
    if (subset == "shading") {
        Attributes& a = mutableAttributes();
        a.surface = from.surface, a.displacement = from.displacement, a.atmosphere = from.atmosphere;
        a.color = from.color, a.opacity = from.opacity, a.lights = from.lights, a.matte = from.matte;
        a.shadingRate = from.shadingRate, a.smoothShading = from.smoothShading;
    } else if (subset == "visibility") {
        Attributes& a = mutableAttributes();
        a.visibleToCamera = from.visibleToCamera, a.castsShadows = from.castsShadows;
    } else if (subset == "geometrymodification") {
        Attributes& a = mutableAttributes();
        a.displacement = from.displacement, a.displacementBound = from.displacementBound;
        a.displacementBoundSpace = from.displacementBoundSpace;
    } else {
        unsupported("resource-subset:" + subset, loc,
                    fmt::format("Resource: subset \"{}\" is not known (expected \"all\", \"shading\", "
                                "\"visibility\" or \"geometrymodification\"); everything is restored", subset));
        m_state = saved;
    }
}

void Builder::resourceBegin(const FileLoc& loc) {
    push(Block::Resource, loc);
    m_blocks.back().savedResources = std::make_shared<std::map<std::string, State>>(m_resources);
}

void Builder::resourceEnd(const FileLoc& loc) {
    OpenBlock b;
    if (pop(Block::Resource, "ResourceEnd", loc, &b)) m_resources = *b.savedResources;
}

void Builder::geometricRepresentation(const std::string& type, const FileLoc& loc) {
    if (type == "primitive") return;
    unsupported("GeometricRepresentation:" + type, loc,
                fmt::format("GeometricRepresentation: \"{}\" is not supported; surfaces are drawn as primitives",
                            type));
}

void Builder::system(const std::string& command, const FileLoc& loc) {
    m_diag.warning(loc, "System: running commands is not supported (ignored)");
}

bool Builder::conditionValue(const std::string& name, ri::ExprValue* out) const {
    auto fromParam = [&](const ri::Param& p) {
        *out = ri::ExprValue{};
        if (p.decl.type == ri::ParamType::String) {
            out->isString = true;
            out->str = p.stringAt(0);
        } else {
            out->num = !p.ints.empty() ? double(p.ints[0]) : double(p.floatAt(0));
        }
        return true;
    };
    auto attribute = [&](const std::string& key) {
        if (key == "identifier:name") {
            *out = ri::ExprValue{true, 0, m_state.attrs->name};
            return true;
        }
        auto it = m_state.attrs->user.find(key);
        return it != m_state.attrs->user.end() && fromParam(it->second);
    };
    auto option = [&](const std::string& key) {
        auto it = m_options.user.find(key);
        return it != m_options.user.end() && fromParam(it->second);
    };
    if (name == "Frame") {
        *out = ri::ExprValue{false, double(m_frame), ""};
        return m_frame >= 0;
    }
    if (name.rfind("Attribute:", 0) == 0) return attribute(name.substr(10));
    if (name.rfind("Option:", 0) == 0) return option(name.substr(7));
    // "$user:pass", or "$pass" for "user:pass": an attribute, else an option.
    const std::string key = name.find(':') == std::string::npos ? "user:" + name : name;
    return attribute(key) || option(key);
}

void Builder::coordSysTransform(const std::string& name, const FileLoc& loc) {
    if (m_world) {
        if (const Mat4* space = m_state.attrs->space(name, m_world->coordinateSystems)) {
            setTransform(*space);
            return;
        }
    } else {
        if (name == "camera") {
            setTransform(Mat4::identity());
            return;
        }
        auto it = m_cameraSpaces.find(name);
        if (it != m_cameraSpaces.end()) {
            setTransform(it->second);
            return;
        }
    }
    m_diag.error(loc, "CoordSysTransform: unknown coordinate system \"{}\" (expected \"world\", \"camera\" or a "
                 "name given to CoordinateSystem)", name);
}

std::string Builder::expandSearchPath(const std::string& kind, const std::string& value) const {
    // '&' is the previous value; before any, the built-in default ('@').
    auto def = m_defaultSearchPaths.find(kind);
    const std::string builtin = def != m_defaultSearchPaths.end() ? def->second : std::string();
    auto prev = m_options.searchPaths.find(kind);
    return umbra::expandSearchPath(value, prev != m_options.searchPaths.end() ? prev->second : builtin, builtin);
}

void Builder::option(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    if (!optionsAllowed("Option", loc)) return;
    for (const ri::Param& p : params.params()) {
        const std::string& pn = p.decl.name;
        if (name == "searchpath") {
            if (p.decl.type != ri::ParamType::String || p.strings.empty()) {
                m_diag.error(p.loc, "Option: searchpath \"{}\" expects a string", pn);
                continue;
            }
            m_options.searchPaths[pn] = expandSearchPath(pn, p.strings[0]);
        } else if (name == "limits" && pn == "bucketsize") {
            int w = params.getInt(pn, 0);
            int h = p.ints.size() >= 2 ? p.ints[1] : (p.floats.size() >= 2 ? int(p.floats[1]) : w);
            if (w < 1 || h < 1 || p.count() * p.decl.elementSize() < 2) {
                m_diag.error(p.loc, "Option: limits \"bucketsize\" expects two positive integers");
                continue;
            }
            m_options.bucketSize[0] = w;
            m_options.bucketSize[1] = h;
            m_options.bucketSizeSet = true;
        } else if (name == "limits" && (pn == "gridsize" || pn == "eyesplits")) {
            int v = params.getInt(pn, 0);
            if (v < (pn == "gridsize" ? 1 : 0)) {
                m_diag.error(p.loc, "Option: limits \"{}\" expects a positive integer, got {}", pn, v);
                continue;
            }
            (pn == "gridsize" ? m_options.gridSize : m_options.eyeSplits) = v;
        } else if (name == "limits" && pn == "archivereads") {
            int v = params.getInt(pn, -1);
            if (v < 0) {
                m_diag.error(p.loc, "Option: limits \"archivereads\" expects an integer of 0 or more, got {}", v);
                continue;
            }
            m_options.archiveReads = v;
        } else if (name == "limits" && pn == "decompressedmb") {
            int v = params.getInt(pn, 0);
            if (v < 1) {
                m_diag.error(p.loc, "Option: limits \"decompressedmb\" expects a positive integer, got {}", v);
                continue;
            }
            m_options.decompressedBytes = uint64_t(v) << 20;
        } else if (name == "shutter" && pn == "offset") {
            m_options.shutterOffset = params.getFloat(pn, 0.0f);
        } else if (name == "shutter" && (pn == "opening" || pn == "shutteropening")) {
            setShutterOpening("Option: shutter", p);
        } else if (name == "statistics" && pn == "endofframe") {
            // PRMan's levels: 1-3 print more and more; above 3 is 3.
            m_options.statisticsEndOfFrame = std::clamp(params.getInt(pn, 0), 0, 3);
        } else if (name == "umbra" && !umbraValueValid("Option", p, m_diag)) {
            continue;
        } else {
            m_options.user[name + ":" + pn] = p;
        }
    }
}

void Builder::format(int xres, int yres, float pixelAspect, const FileLoc& loc) {
    if (!optionsAllowed("Format", loc)) return;
    // A value of zero or less asks for the default (PRMan, Aqsis and Pixie
    // read `Format 640 480 -1` so); the pixel aspect ratio says nothing else.
    const Options defaults;
    if (xres < 1 || yres < 1)
        m_diag.warning(loc, "Format: resolution {} {} is not positive; using the default {} {}", xres, yres,
                       xres < 1 ? defaults.xResolution : xres, yres < 1 ? defaults.yResolution : yres);
    m_options.xResolution = xres < 1 ? defaults.xResolution : xres;
    m_options.yResolution = yres < 1 ? defaults.yResolution : yres;
    m_options.pixelAspectRatio = pixelAspect > 0 && std::isfinite(pixelAspect) ? pixelAspect : 1.0f;
}

void Builder::fitFrameAspectRatio(Options& o) {
    // RI Spec 3.2: the picture "is adjusted in size so that it fits into the
    // display area" with the frame aspect ratio, its upper left corner at
    // the display's: the largest such rectangle of whole pixels (Pixie
    // writes an image of that size). The frame's copy only, so a later
    // frame's FrameAspectRatio fits the Format as given.
    if (!(o.frameAspectRatio > 0)) return;
    const double display = double(o.xResolution) * o.pixelAspectRatio / double(o.yResolution);
    if (o.frameAspectRatio < display)
        o.xResolution = std::max(1, int(std::lround(o.yResolution * o.frameAspectRatio / o.pixelAspectRatio)));
    else if (o.frameAspectRatio > display)
        o.yResolution = std::max(1, int(std::lround(o.xResolution * o.pixelAspectRatio / o.frameAspectRatio)));
}

void Builder::frameAspectRatio(float aspect, const FileLoc& loc) {
    if (!optionsAllowed("FrameAspectRatio", loc)) return;
    if (!(aspect > 0)) {
        m_diag.error(loc, "FrameAspectRatio: expected a positive ratio, got {}", aspect);
        return;
    }
    m_options.frameAspectRatio = aspect;
}

void Builder::screenWindow(float left, float right, float bottom, float top, const FileLoc& loc) {
    if (!optionsAllowed("ScreenWindow", loc)) return;
    if (left == right || bottom == top) {
        m_diag.error(loc, "ScreenWindow: the window is empty ({} {} {} {})", left, right, bottom, top);
        return;
    }
    m_options.screenWindowSet = true;
    m_options.screenWindow[0] = left;
    m_options.screenWindow[1] = right;
    m_options.screenWindow[2] = bottom;
    m_options.screenWindow[3] = top;
}

void Builder::cropWindow(float xmin, float xmax, float ymin, float ymax, const FileLoc& loc) {
    if (!optionsAllowed("CropWindow", loc)) return;
    xmin = clamp(xmin, 0.0f, 1.0f), xmax = clamp(xmax, 0.0f, 1.0f);
    ymin = clamp(ymin, 0.0f, 1.0f), ymax = clamp(ymax, 0.0f, 1.0f);
    if (!(xmin < xmax && ymin < ymax)) {
        m_diag.error(loc, "CropWindow: expected xmin < xmax and ymin < ymax within [0, 1]");
        return;
    }
    m_options.cropWindow[0] = xmin;
    m_options.cropWindow[1] = xmax;
    m_options.cropWindow[2] = ymin;
    m_options.cropWindow[3] = ymax;
}

void Builder::projection(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    if (!optionsAllowed("Projection", loc)) return;
    if (name == "perspective") {
        float fov = params.getFloat("fov", 90.0f);
        if (!(fov > 0 && fov < 180)) {
            m_diag.error(loc, "Projection: \"fov\" must be between 0 and 180 degrees, got {}", fov);
            return;
        }
        m_options.projection = Projection::Perspective;
        m_options.fov = fov;
    } else if (name == "orthographic") {
        m_options.projection = Projection::Orthographic;
    } else {
        m_diag.error(loc, "Projection: unknown projection \"{}\" (expected \"perspective\" or \"orthographic\")", name);
        return;
    }
    params.reportUnused(m_diag, "Projection");
    // RI spec: transforms before Projection are the screen transformation;
    // the current transform is cleared after it, so camera transforms
    // follow it.
    takeScreenTransform(loc);
    setTransform(Mat4::identity());
}

void Builder::takeScreenTransform(const FileLoc& loc) {
    if (m_state.motion)
        m_diag.warning(loc, "Projection: a moving screen transformation (MotionBegin before Projection) is not "
                            "supported; its transform at the shutter's opening is used");
    const Mat4& t = m_state.transform;
    // Screen (x, y, z, 1) -> t * (x, y, z, 1): a = t[0][0], b = t[0][1],
    // c = t[1][0], d = t[1][1] is the x/y part, t[0][3], t[1][3] the offset.
    const float a = t.m[0][0], b = t.m[0][1], c = t.m[1][0], d = t.m[1][1];
    const float size = std::max({std::abs(a), std::abs(b), std::abs(c), std::abs(d)});
    const float eps = 1e-6f * std::max(size, 1.0f);
    // Rotation, shear, scale and mirror are all kept. Entries that are only
    // rounding (the cosine of a quarter turn) become exact zeros, so a
    // quarter turn is an exact permutation and a still image stays diagonal.
    float linear[4] = {a, b, c, d};
    for (float& e : linear)
        if (std::abs(e) <= 1e-7f * size) e = 0;
    // Flattened to a line (or a point): no picture. Relative to the size,
    // so a tiny uniform scale still counts.
    const double det = double(linear[0]) * linear[3] - double(linear[1]) * linear[2];
    const bool degenerate = !(std::abs(det) > 1e-10 * double(size) * size) || !std::isfinite(det) || !(size > 1e-20f);
    if (degenerate) {
        m_diag.warning(loc, "Projection: the screen transformation scales the image to nothing; ignored");
        linear[0] = linear[3] = 1;
        linear[1] = linear[2] = 0;
    }
    bool depth = std::abs(t.m[2][2] - 1) > eps || std::abs(t.m[2][3]) > eps;
    for (int i = 0; i < 2; ++i) depth |= std::abs(t.m[2][i]) > eps || std::abs(t.m[i][2]) > eps;
    if (depth)
        m_diag.warning(loc, "Projection: the screen transformation changes depth (e.g. a Scale or Translate of z "
                            "before Projection); umbra keeps camera depth, the depth part is dropped");
    bool projective = std::abs(t.m[3][3] - 1) > eps;
    for (int i = 0; i < 3; ++i) projective |= std::abs(t.m[3][i]) > eps;
    if (projective)
        m_diag.warning(loc, "Projection: the screen transformation is projective (a Perspective before "
                            "Projection); only its affine x/y part (scale, rotation, shear, offset) is used");
    const float w = projective && std::abs(t.m[3][3]) > eps ? t.m[3][3] : 1.0f;
    for (int i = 0; i < 4; ++i) m_options.screenLinear[i] = degenerate ? linear[i] : linear[i] / w;
    m_options.screenOffset[0] = std::isfinite(t.m[0][3] / w) ? t.m[0][3] / w : 0.0f;
    m_options.screenOffset[1] = std::isfinite(t.m[1][3] / w) ? t.m[1][3] / w : 0.0f;
}

void Builder::clipping(float nearZ, float farZ, const FileLoc& loc) {
    if (!optionsAllowed("Clipping", loc)) return;
    if (!(nearZ > 0 && farZ > nearZ)) {
        m_diag.error(loc, "Clipping: expected 0 < near < far, got {} {}", nearZ, farZ);
        return;
    }
    m_options.nearClip = nearZ;
    m_options.farClip = farZ;
}

void Builder::clippingPlane(const Vec3& point, const Vec3& normal, const FileLoc& loc) {
    unsupported("ClippingPlane", loc, "ClippingPlane: not supported (ignored)");
}

void Builder::depthOfField(const std::vector<float>& args, const FileLoc& loc) {
    if (!optionsAllowed("DepthOfField", loc)) return;
    if (args.empty()) {  // the pinhole camera again
        m_options.fstop = kInfinity;
        return;
    }
    const float fstop = args[0], focalLength = args[1], focalDistance = args[2];
    if (!(fstop > 0) || !(focalLength > 0) || !(focalDistance > 0)) {
        m_diag.error(loc, "DepthOfField: expected fstop, focallength and focaldistance > 0, got {} {} {} (ignored)",
                     fstop, focalLength, focalDistance);
        return;
    }
    m_options.fstop = fstop;
    m_options.focalLength = focalLength;
    m_options.focalDistance = focalDistance;
}

void Builder::shutter(float open, float close, const FileLoc& loc) {
    if (!optionsAllowed("Shutter", loc)) return;
    if (close < open) {
        m_diag.error(loc, "Shutter: expected opentime <= closetime, got {} {}", open, close);
        return;
    }
    m_options.shutter[0] = open;
    m_options.shutter[1] = close;
}

void Builder::pixelVariance(float v, const FileLoc& loc) {
    unsupported("PixelVariance", loc, "PixelVariance: adaptive sampling is not supported (ignored)");
}

void Builder::pixelSamples(float xs, float ys, const FileLoc& loc) {
    if (!optionsAllowed("PixelSamples", loc)) return;
    if (!(xs >= 1 && ys >= 1)) {
        m_diag.error(loc, "PixelSamples: expected sample counts of at least 1, got {} {}", xs, ys);
        return;
    }
    if (xs > kMaxPixelSamples || ys > kMaxPixelSamples) {
        // The sample buffer and the filter's weight tables grow with the
        // samples of a pixel: 1000 x 1000 would need gigabytes per bucket.
        const float cx = std::min(xs, float(kMaxPixelSamples)), cy = std::min(ys, float(kMaxPixelSamples));
        m_diag.warning(loc, "PixelSamples: {} {} exceeds the maximum of {} samples along each axis of a pixel; "
                       "clamped to {} {}", xs, ys, kMaxPixelSamples, cx, cy);
        xs = cx;
        ys = cy;
    }
    // Fractional rates round up to whole samples per pixel.
    m_options.pixelSamples[0] = int(std::ceil(xs - 1e-4f));
    m_options.pixelSamples[1] = int(std::ceil(ys - 1e-4f));
}

void Builder::pixelFilter(const std::string& name, float xwidth, float ywidth, const FileLoc& loc) {
    if (!optionsAllowed("PixelFilter", loc)) return;
    static const char* kFilters[] = {"box",  "triangle", "gaussian", "catmull-rom", "sinc", "mitchell",
                                     "separable-catmull-rom", "blackman-harris", "disk", "bessel"};
    // PRMan's "lanczos" is sinc(x) sinc(x / radius): umbra's windowed sinc.
    std::string n = name == "catmullrom" ? "catmull-rom" : name == "lanczos" ? "sinc" : name;
    if (std::find_if(std::begin(kFilters), std::end(kFilters), [&](const char* f) { return n == f; }) ==
        std::end(kFilters)) {
        m_diag.error(loc, "PixelFilter: unknown filter \"{}\" (expected box, triangle, gaussian, catmull-rom, sinc, "
                     "lanczos, mitchell, separable-catmull-rom, blackman-harris, disk or bessel)", name);
        return;
    }
    if (!(xwidth > 0 && ywidth > 0)) {
        m_diag.error(loc, "PixelFilter: expected positive widths, got {} {}", xwidth, ywidth);
        return;
    }
    if (xwidth > kMaxFilterWidth || ywidth > kMaxFilterWidth) {
        // Every bucket samples the filter's reach around it: a width of
        // 1e6 pixels would sample the whole frame, for every bucket.
        const float cx = std::min(xwidth, kMaxFilterWidth), cy = std::min(ywidth, kMaxFilterWidth);
        m_diag.warning(loc, "PixelFilter: widths {} {} exceed the maximum of {} pixels; clamped to {} {}", xwidth,
                       ywidth, kMaxFilterWidth, cx, cy);
        xwidth = cx;
        ywidth = cy;
    }
    m_options.pixelFilter = n;
    m_options.filterWidth[0] = xwidth;
    m_options.filterWidth[1] = ywidth;
}

void Builder::exposure(float gain, float gamma, const FileLoc& loc) {
    if (!optionsAllowed("Exposure", loc)) return;
    if (!(gain > 0 && gamma > 0)) {
        m_diag.error(loc, "Exposure: expected positive gain and gamma, got {} {}", gain, gamma);
        return;
    }
    m_options.exposureGain = gain;
    m_options.exposureGamma = gamma;
}

void Builder::imager(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    if (!optionsAllowed("Imager", loc)) return;
    if (name.empty() || name == "null")
        m_options.imager.reset();
    else
        m_options.imager = makeShader(name, std::move(params), loc);
}

void Builder::quantize(const std::string& type, float one, float qmin, float qmax, float dither, const FileLoc& loc) {
    if (!optionsAllowed("Quantize", loc)) return;
    if (qmin > qmax || one < 0 || dither < 0) {
        m_diag.error(loc, "Quantize: expected one >= 0, min <= max and ditheramplitude >= 0");
        return;
    }
    if (type == "rgba") {
        m_options.quantizeOne = one, m_options.quantizeMin = qmin;
        m_options.quantizeMax = qmax, m_options.quantizeDither = dither;
    } else if (type == "z") {
        m_options.zQuantizeOne = one, m_options.zQuantizeMin = qmin;
        m_options.zQuantizeMax = qmax, m_options.zQuantizeDither = dither;
    } else if (!type.empty()) {
        // RenderMan 13+: the quantization of the output called `type`.
        m_options.namedQuantize[type] = {one, qmin, qmax, dither};
    } else {
        m_diag.error(loc, "Quantize: expected a type (\"rgba\", \"z\" or an output's name)");
    }
}

void Builder::display(const std::string& name, const std::string& driver, const std::string& mode,
                      ri::ParamList params, const FileLoc& loc) {
    if (!optionsAllowed("Display", loc)) return;
    if (name.empty() || name == "+" || driver.empty() || mode.empty()) {
        m_diag.error(loc, "Display: expected a non-empty name, type and mode");
        return;
    }
    DisplayRecord d;
    bool add = name[0] == '+';
    d.name = add ? name.substr(1) : name;
    d.driver = driver;
    d.mode = mode;
    auto declared = m_declarations.find(mode);
    if (declared != m_declarations.end()) d.mode = declared->second.str();
    d.params = std::move(params);
    d.loc = loc;
    if (!add) m_options.displays.clear();
    m_options.displays.push_back(std::move(d));
}

void Builder::displayChannel(const std::string& channel, ri::ParamList params, const FileLoc& loc) {
    if (!optionsAllowed("DisplayChannel", loc)) return;
    DisplayRecord d;
    d.name = channel;
    d.params = std::move(params);
    d.loc = loc;
    m_options.displayChannels.push_back(std::move(d));
}

void Builder::hider(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    if (!optionsAllowed("Hider", loc)) return;
    if (name != "hidden" && name != "stochastic")
        unsupported("hider:" + name, loc, fmt::format("Hider: \"{}\" is not supported; \"hidden\" is used", name));
    if (const ri::Param* p = params.find("depthfilter")) {
        // Exporters write "" for "not set" (Blender-to-Renderman): Aqsis
        // and Pixie render such frames with "min", and so does umbra, with
        // a warning. PRMan's "max" and "average" are umbra's too (Pixie's
        // values; they were refused).
        const std::string& f = p->stringAt(0);
        if (f == "min" || f == "max" || f == "average" || f == "second" || f == "midpoint" || f == "dual") {
            m_options.depthFilter = f;
        } else {
            m_diag.warning(p->loc, "Hider: \"depthfilter\" \"{}\" is not one umbra has (\"min\", \"max\", "
                           "\"average\", \"second\", \"midpoint\", \"dual\"); \"min\" is used", f);
            m_options.depthFilter = "min";
        }
    }
    if (params.find("jitter")) m_options.jitter = params.getInt("jitter", 1) != 0;
    m_options.hider = name;
    m_options.hiderParams = std::move(params);
}

void Builder::colorSamples(const std::vector<float>& nRGB, const std::vector<float>& RGBn, const FileLoc& loc) {
    // Exporters write the identity (RGB as RGB): that is what umbra does.
    auto identity3 = [](const std::vector<float>& m) {
        if (m.size() != 9) return false;
        for (int i = 0; i < 9; ++i)
            if (m[size_t(i)] != (i % 4 == 0 ? 1.0f : 0.0f)) return false;
        return true;
    };
    if (identity3(nRGB) && identity3(RGBn)) return;
    unsupported("ColorSamples", loc, "ColorSamples: only RGB colour is supported (ignored)");
}

void Builder::relativeDetail(float v, const FileLoc& loc) {
    if (!optionsAllowed("RelativeDetail", loc)) return;
    if (!(v > 0) || !std::isfinite(v)) {
        m_diag.error(loc, "RelativeDetail: expected a positive number, got {} (ignored)", v);
        return;
    }
    m_options.relativeDetail = v;
}

void Builder::attribute(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    for (const ri::Param& p : params.params()) {
        const std::string& pn = p.decl.name;
        // A primitive's data after an Attribute (an exporter that lost the
        // primitive request: the LEGO brick exporter writes "P", "N" and
        // "facevarying float[2] uv0" after Attribute "identifier"): no
        // attribute takes a value per vertex. Pixie and Aqsis say so too.
        static const char* const kVertexData[] = {"P", "Pw", "Pz", "N", "Np", "Cs", "Os", "st", "s", "t"};
        const bool perVertex = p.decl.storage != ri::StorageClass::Constant && p.decl.storage != ri::StorageClass::Uniform;
        if (perVertex || std::find(std::begin(kVertexData), std::end(kVertexData), pn) != std::end(kVertexData)) {
            m_diag.warningOnce("attribute-vertexdata:" + name + ":" + pn, p.loc,
                               "Attribute \"{}\": \"{}\" is a primitive's data, not an attribute (ignored; is a "
                               "primitive request missing before it?)",
                               name, pn);
            continue;
        }
        if (name == "displacementbound" && pn == "sphere") {
            float r = params.getFloat(pn, 0);
            if (!(r >= 0)) {
                m_diag.error(p.loc, "Attribute: displacementbound \"sphere\" expects a radius >= 0, got {}", r);
                continue;
            }
            mutableAttributes().displacementBound = r;
        } else if (name == "displacementbound" && pn == "coordinatesystem") {
            mutableAttributes().displacementBoundSpace = params.getString(pn, "object");
        } else if (name == "identifier" && pn == "name") {
            mutableAttributes().name = params.getString(pn, "");
        } else if (name == "visibility" && pn == "camera") {
            mutableAttributes().visibleToCamera = params.getInt(pn, 1) != 0;
        } else if (name == "visibility" && (pn == "transmission" || pn == "shadow")) {
            // Older RIBs give transmission as "opaque"/"transparent".
            bool casts = p.decl.type == ri::ParamType::String ? p.stringAt(0) != "transparent"
                                                              : params.getInt(pn, 1) != 0;
            mutableAttributes().castsShadows = casts;
        } else if (name == "dice" && pn == "binary") {
            mutableAttributes().binaryDice = params.getInt(pn, 0) != 0;
            mutableAttributes().user[name + ":" + pn] = p;
        } else if (name == "render" && pn == "casts_shadows" && p.decl.type == ri::ParamType::String) {
            // BMRT's spelling: "none" casts no shadows; "opaque", "Os" and
            // "shade" all cast one (umbra's depth maps are opaque).
            mutableAttributes().castsShadows = p.stringAt(0) != "none";
            mutableAttributes().user[name + ":" + pn] = p;
        } else if (name == "umbra" && !umbraValueValid("Attribute", p, m_diag)) {
            continue;
        } else {
            mutableAttributes().user[name + ":" + pn] = p;
        }
    }
}

void Builder::color(const Color& c, const FileLoc& loc) {
    if (skipMotionSample("Color", loc)) return;
    mutableAttributes().color = c;
}

void Builder::opacity(const Color& c, const FileLoc& loc) {
    if (skipMotionSample("Opacity", loc)) return;
    mutableAttributes().opacity = c;
}

void Builder::textureCoordinates(const std::array<float, 8>& st, const FileLoc& loc) {
    std::copy(st.begin(), st.end(), mutableAttributes().textureCoordinates);
}

void Builder::matte(bool on, const FileLoc& loc) { mutableAttributes().matte = on; }

void Builder::shadingRate(float rate, const FileLoc& loc) {
    if (!(rate > 0)) {
        m_diag.error(loc, "ShadingRate: expected a positive area in pixels, got {}", rate);
        return;
    }
    if (rate < kMinShadingRate) {
        // Finer only multiplies micropolygons (1e-6 would make a million a
        // pixel). An attribute may be set per object: reported once.
        m_diag.warningOnce("limit:ShadingRate", loc, "ShadingRate: {} is below the minimum of 1/64 pixel; clamped "
                           "to 0.015625", rate);
        rate = kMinShadingRate;
    }
    mutableAttributes().shadingRate = rate;
}

void Builder::shadingInterpolation(const std::string& type, const FileLoc& loc) {
    if (type != "constant" && type != "smooth") {
        m_diag.error(loc, "ShadingInterpolation: unknown type \"{}\" (expected \"constant\" or \"smooth\")", type);
        return;
    }
    mutableAttributes().smoothShading = type == "smooth";
}

void Builder::sides(int n, const FileLoc& loc) {
    if (n != 1 && n != 2) {
        m_diag.error(loc, "Sides: expected 1 or 2, got {}", n);
        return;
    }
    mutableAttributes().sides = n;
}

void Builder::orientation(const std::string& o, const FileLoc& loc) {
    // The attribute is kept relative to the current coordinate system
    // (Attributes::insideOut), so "lh" and "rh" compare with its handedness.
    const bool left = currentIsLeft(m_state.transform);
    bool insideOut;
    if (o == "outside")
        insideOut = false;
    else if (o == "inside")
        insideOut = true;
    else if (o == "lh")
        insideOut = !left;
    else if (o == "rh")
        insideOut = left;
    else {
        m_diag.error(loc, "Orientation: unknown orientation \"{}\" (expected \"outside\", \"inside\", \"lh\" or "
                     "\"rh\")", o);
        return;
    }
    if (m_state.attrs->insideOut != insideOut) mutableAttributes().insideOut = insideOut;
}

void Builder::reverseOrientation(const FileLoc&) { mutableAttributes().insideOut = !m_state.attrs->insideOut; }

void Builder::basis(const ri::BasisSpec& u, int ustep, const ri::BasisSpec& v, int vstep, const FileLoc& loc) {
    Basis b[2];
    const ri::BasisSpec* spec[2] = {&u, &v};
    int steps[2] = {ustep, vstep};
    for (int k = 0; k < 2; ++k) {
        if (!spec[k]->name.empty()) {
            if (!Basis::byName(spec[k]->name, &b[k])) {
                m_diag.error(loc, "Basis: unknown basis \"{}\" (expected bezier, b-spline, catmull-rom, hermite, "
                             "power or an array of 16 numbers)", spec[k]->name);
                return;
            }
        } else {
            for (int i = 0; i < 4; ++i)
                for (int j = 0; j < 4; ++j) b[k].m[i][j] = spec[k]->matrix[i * 4 + j];
        }
        if (steps[k] < 1 || steps[k] > 4) {
            m_diag.error(loc, "Basis: {} must be between 1 and 4, got {}", k == 0 ? "ustep" : "vstep", steps[k]);
            return;
        }
        b[k].step = steps[k];
    }
    Attributes& a = mutableAttributes();
    a.uBasis = b[0];
    a.vBasis = b[1];
}

void Builder::bound(const std::array<float, 6>& b, const FileLoc& loc) {
    // A culling hint only; primitives compute their own bounds.
}

void Builder::detail(const std::array<float, 6>& b, const FileLoc& loc) {
    if (!(b[0] <= b[1] && b[2] <= b[3] && b[4] <= b[5])) {
        m_diag.error(loc, "Detail: expected a bound xmin xmax ymin ymax zmin zmax with each min <= max (ignored)");
        return;
    }
    Attributes& a = mutableAttributes();
    a.hasDetail = true;
    for (int k = 0; k < 8; ++k)
        a.detailCorners[size_t(k)] = m_state.transform.point(Vec3(b[k & 1], b[2 + ((k >> 1) & 1)], b[4 + (k >> 2)]));
}

void Builder::detailRange(const std::array<float, 4>& r, const FileLoc& loc) {
    if (!(r[0] >= 0 && r[0] <= r[1] && r[1] <= r[2] && r[2] <= r[3])) {
        m_diag.error(loc, "DetailRange: expected 0 <= minvisible <= lowertransition <= uppertransition <= "
                     "maxvisible (ignored)");
        return;
    }
    if (!m_state.attrs->hasDetail)
        m_diag.warningOnce("detailrange-without-detail", loc,
                           "DetailRange: no Detail bound is set, so the range cannot be measured (drawn always)");
    mutableAttributes().detailRange = r;
}

void Builder::geometricApproximation(const std::string& type, float value, const FileLoc& loc) {
    // "flatness" (RI Spec 3.2) and PRMan's "motionfactor" are honoured;
    // another renderer's ("tesselation", "focusfactor", ...) would
    // otherwise be kept without effect and without a word.
    if (type != "flatness" && type != "motionfactor")
        unsupported("GeometricApproximation:" + type, loc,
                    fmt::format("GeometricApproximation \"{}\": not a type umbra knows (it knows \"flatness\" and "
                                "\"motionfactor\"); ignored",
                                type));
    ri::Param p;
    p.decl.name = type;
    p.decl.type = ri::ParamType::Float;
    p.floats = {value};
    p.loc = loc;
    mutableAttributes().user["GeometricApproximation:" + type] = std::move(p);
}

void Builder::surface(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    if (skipMotionSample("Surface", loc)) return;
    mutableAttributes().surface = makeShader(name, std::move(params), loc);
}

void Builder::displacement(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    if (skipMotionSample("Displacement", loc)) return;
    mutableAttributes().displacement = makeShader(name, std::move(params), loc);
}

void Builder::atmosphere(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    if (skipMotionSample("Atmosphere", loc)) return;
    mutableAttributes().atmosphere = makeShader(name, std::move(params), loc);
}

void Builder::interior(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    unsupported("volume", loc, "Interior: interior and exterior volume shaders are not supported (ignored)");
}

void Builder::exterior(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    unsupported("volume", loc, "Exterior: interior and exterior volume shaders are not supported (ignored)");
}

void Builder::deformation(const std::string& name, ri::ParamList params, const FileLoc& loc) {
    unsupported("Deformation", loc, "Deformation: transformation shaders are not supported (ignored)");
}

bool Builder::lightAllowed(const char* request, const std::string& name, const std::string& handle,
                           const ri::ParamList& params, const FileLoc& loc) {
    if (!m_objectHandle.empty()) {
        m_diag.error(loc, "{}: lights are not allowed inside ObjectBegin/ObjectEnd (ignored)", request);
        return false;
    }
    if (m_world) return true;
    // Before WorldBegin: kept and turned on in the world, as PRMan, Aqsis
    // and Pixie do; its shader space is where it was given.
    m_preWorldLights.push_back({name, handle, params, m_state.transform, std::string_view(request) != "LightSource", loc});
    return false;
}

void Builder::lightSource(const std::string& name, const std::string& handle, ri::ParamList params,
                          const FileLoc& loc) {
    addLight("LightSource", name, handle, std::move(params), loc, false);
}

void Builder::areaLightSource(const std::string& name, const std::string& handle, ri::ParamList params,
                              const FileLoc& loc) {
    // Pixie and Aqsis (and PRMan before ray tracing) light from the shader
    // alone: P is the shader space's origin, the block's primitives are
    // drawn but do not emit. umbra does the same, so the scene is lit as
    // there; it turned the light off.
    unsupported("AreaLightSource", loc,
                "AreaLightSource: lit as an ordinary light from its shader space (its primitives are drawn, not "
                "sampled as an emitter), as Pixie and Aqsis do");
    addLight("AreaLightSource", name, handle, std::move(params), loc, true);
}

void Builder::addLight(const char* request, const std::string& name, const std::string& handle,
                       ri::ParamList params, const FileLoc& loc, bool area) {
    if (m_procedural) {
        m_diag.error(loc, "{}: not allowed in a procedural primitive's RIB, whose lights are the world's (ignored)",
                     request);
        return;
    }
    if (!lightAllowed(request, name, handle, params, loc)) return;
    if (skipMotionSample(request, loc)) return;
    LightRecord l;
    l.shader = *makeShader(name, std::move(params), loc);
    l.handle = handle;
    l.area = area;
    int index = int(m_world->lights.size());
    Attributes& a = mutableAttributes();
    a.lights.push_back(index);
    l.attributes = m_state.attrs;
    m_world->lights.push_back(std::move(l));
    m_lightHandles[handle] = index;
}

void Builder::illuminate(const std::string& handle, bool on, const FileLoc& loc) {
    if (!m_world) {
        // A light given before WorldBegin (PRMan, Pixie and Aqsis take
        // Illuminate there too): whether it starts on in the world.
        for (auto l = m_preWorldLights.rbegin(); l != m_preWorldLights.rend(); ++l)
            if (l->handle == handle) {
                l->on = on;
                return;
            }
        m_diag.error(loc, "Illuminate: unknown light handle \"{}\" (expected the handle of a LightSource given "
                     "before it)", handle);
        return;
    }
    auto it = m_lightHandles.find(handle);
    if (it == m_lightHandles.end()) {
        m_diag.error(loc, "Illuminate: unknown light handle \"{}\" (expected the handle of a LightSource)", handle);
        return;
    }
    int index = it->second;
    const std::vector<int>& cur = m_state.attrs->lights;
    bool present = std::find(cur.begin(), cur.end(), index) != cur.end();
    if (on == present) return;
    std::vector<int>& lights = mutableAttributes().lights;
    if (on)
        lights.push_back(index);
    else
        lights.erase(std::find(lights.begin(), lights.end(), index));
}

void Builder::trimCurve(const ri::RequestArgs& args, const FileLoc& loc) {
    // Arguments: ncurves order n as integer arrays; knot min max u v w
    // flattened into floats, split here by the counts.
    if (args.intArrays.size() != 3) {
        m_diag.error(loc, "TrimCurve: expected 3 integer arrays (ncurves order n), got {}", args.intArrays.size());
        return;
    }
    auto rec = std::make_shared<TrimCurveRecord>();
    rec->ncurves = args.intArrays[0];
    rec->order = args.intArrays[1];
    rec->n = args.intArrays[2];
    rec->loc = loc;
    long curves = 0;
    for (size_t l = 0; l < rec->ncurves.size(); ++l) {
        if (rec->ncurves[l] < 1) {
            m_diag.error(loc, "TrimCurve: loop {} has {} curves, expected at least 1", l, rec->ncurves[l]);
            return;
        }
        curves += rec->ncurves[l];
    }
    if (long(rec->order.size()) != curves || long(rec->n.size()) != curves) {
        m_diag.error(loc, "TrimCurve: order and n need one value per curve ({}), got {} and {}", curves,
                     rec->order.size(), rec->n.size());
        return;
    }
    size_t knots = 0, points = 0;
    for (long c = 0; c < curves; ++c) {
        const int order = rec->order[size_t(c)], n = rec->n[size_t(c)];
        if (order < 1 || order > 31 || n < order) {
            m_diag.error(loc, "TrimCurve: curve {} has order {} and n {}, expected 1 <= order <= 31 and n >= order", c,
                         order, n);
            return;
        }
        knots += size_t(n + order);
        points += size_t(n);
    }
    const size_t expected = knots + 2 * size_t(curves) + 3 * points;
    if (args.floats.size() != expected) {
        m_diag.error(loc, "TrimCurve: expected {} floats ({} knots, min and max per curve, u v w per point), got {}",
                     expected, knots, args.floats.size());
        return;
    }
    auto take = [it = args.floats.begin()](std::vector<float>& into, size_t count) mutable {
        into.assign(it, it + long(count));
        it += long(count);
    };
    take(rec->knot, knots);
    take(rec->min, size_t(curves));
    take(rec->max, size_t(curves));
    take(rec->u, points);
    take(rec->v, points);
    take(rec->w, points);
    // No loops: no trimming from here on.
    mutableAttributes().trimCurves = curves > 0 ? std::move(rec) : nullptr;
}

void Builder::primitive(const std::string& type, ri::RequestArgs args, ri::ParamList params, const FileLoc& loc) {
    if (!requireWorld(type, loc)) return;
    if (type == "Procedural2") {
        // RenderMan 19+: Procedural2 "DelayedReadArchive2" "SimpleBound"
        // "string filename" [...] "float[6] bound" [...], as RenderMan for
        // Maya writes its geometry: the DelayedReadArchive it stands for.
        const std::string name = args.strings.empty() ? std::string() : args.strings[0];
        if (name != "DelayedReadArchive2") {
            unsupported("Procedural2:" + name, loc,
                        fmt::format("Procedural2 \"{}\": a RenderMan 19+ procedural umbra does not have (skipped; "
                                    "\"DelayedReadArchive2\" is read)", name));
            return;
        }
        const ri::Param* file = params.find("filename");
        const ri::Param* bound = params.find("bound");
        if (!file || file->strings.empty() || !bound || bound->floats.size() != 6) {
            m_diag.error(loc, "Procedural2 \"DelayedReadArchive2\": expected \"string filename\" and \"float[6] "
                              "bound\" (skipped)");
            return;
        }
        ri::RequestArgs archive;
        archive.strings = {"DelayedReadArchive", file->strings[0]};
        archive.floats = bound->floats;
        primitive("Procedural", std::move(archive), ri::ParamList(), loc);
        return;
    }
    if (type == "Procedural" && !proceduralValid(args, loc)) return;
    if (type == "Geometry" && (args.strings.empty() || args.strings[0] != "teapot")) {
        const std::string name = args.strings.empty() ? std::string() : args.strings[0];
        const bool known = std::find_if(std::begin(kOtherGeometryNames), std::end(kOtherGeometryNames),
                                        [&](const char* n) { return name == n; }) != std::end(kOtherGeometryNames);
        unsupported("Geometry:" + name, loc,
                    fmt::format("Geometry \"{}\": {}; umbra draws only \"teapot\" (skipped)", name,
                                known ? "drawn by some other renderers" : "unknown"));
        return;
    }
    PrimitiveRecord r;
    r.type = type;
    r.floatArgs = std::move(args.floats);
    r.intArgs = std::move(args.ints);
    r.stringArgs = std::move(args.strings);
    r.intArrays = std::move(args.intArrays);
    r.params = std::move(params);
    r.loc = loc;
    if (m_motion && !m_blocks.empty() && m_blocks.back().kind == Block::Motion) {
        // Deformation blur: the block's primitives are one primitive's shapes.
        if (++m_motion->requests > 1 && m_motion->shapes.empty()) {
            m_diag.warningOnce("motion:mixed", m_motion->loc, "MotionBegin: a block mixing primitives and "
                               "transforms blurs the transforms only");
            return;
        }
        if (m_motion->times.empty() && m_motion->requests > 1) return;
        placeRecord(r);
        m_motion->shapes.push_back(std::move(r));
        return;
    }
    placeRecord(r);
    emitPrimitive(std::move(r));
}

bool Builder::proceduralValid(ri::RequestArgs& args, const FileLoc& loc) {
    const std::string name = args.strings.empty() ? std::string() : args.strings[0];
    const ProceduralKind* kind = nullptr;
    for (const ProceduralKind& k : kProceduralKinds)
        if (name == k.name) kind = &k;
    if (!kind) {
        m_diag.error(loc, "Procedural: unknown procedural \"{}\" (expected \"DelayedReadArchive\", \"RunProgram\" or "
                     "\"DynamicLoad\"; skipped)", name);
        return false;
    }
    // The parser gives the name, then the args array's strings.
    if (args.strings.size() < 1 + kind->strings) {
        if (kind->strings == 2 && args.strings.size() == 2) return boundValid(args, loc);  // no data block: ""
        m_diag.error(loc, "Procedural \"{}\": expected the arguments {}, got {} strings (skipped)", name, kind->what,
                     args.strings.size() - 1);
        return false;
    }
    return boundValid(args, loc);
}

bool Builder::boundValid(ri::RequestArgs& args, const FileLoc& loc) {
    std::vector<float>& b = args.floats;
    if (b.size() != 6) {
        m_diag.error(loc, "Procedural: expected a bound of 6 floats [xmin xmax ymin ymax zmin zmax], got {} (skipped)",
                     b.size());
        return false;
    }
    for (int a = 0; a < 3; ++a) {
        float& lo = b[size_t(2 * a)];
        float& hi = b[size_t(2 * a + 1)];
        if (lo > hi) {
            // Written max first: Pixie and Aqsis take the range it spans.
            m_diag.warning(loc, "Procedural: the bound's {} range [{} {}] is written max first (expected min <= max; "
                           "read as [{} {}])", "xyz"[a], lo, hi, hi, lo);
            std::swap(lo, hi);
        }
        if (!(lo <= hi)) {
            m_diag.error(loc, "Procedural: the bound's {} range [{} {}] is not a number (skipped)", "xyz"[a], lo, hi);
            return false;
        }
    }
    return true;
}

void Builder::beginProcedural(const WorldRecord& world, const PrimitiveRecord& procedural) {
    m_options = world.options;
    m_frame = world.frameNumber;
    m_world = std::make_unique<WorldRecord>();
    m_world->frameNumber = world.frameNumber;
    m_world->options = world.options;
    m_world->coordinateSystems = world.coordinateSystems;
    m_world->lights = world.lights;
    m_world->loc = world.loc;
    m_lightHandles.clear();
    for (size_t i = 0; i < world.lights.size(); ++i) m_lightHandles[world.lights[i].handle] = int(i);
    m_procedural = true;
    // The record keeps its reference, so the first attribute request copies
    // (mutableAttributes) and the procedural's own attributes never change.
    m_state.attrs = std::const_pointer_cast<Attributes>(procedural.attributes);
    m_state.transform = procedural.worldFromObject;
    m_state.motion = procedural.worldFromObjectMotion;
}

std::vector<PrimitiveRecord> Builder::takePrimitives() {
    return m_world ? std::move(m_world->primitives) : std::vector<PrimitiveRecord>();
}

void Builder::placeRecord(PrimitiveRecord& r) const {
    r.worldFromObject = m_state.transform;
    r.worldFromObjectMotion = m_state.motion;
    r.attributes = m_state.attrs;
}

void Builder::emitPrimitive(PrimitiveRecord r) {
    if (!m_objectHandle.empty()) {
        // Inside a definition the record is relative to the object's space;
        // an instance supplies the rest (and its own motion).
        Mat4 objectFromPrim = m_objectFromCurrentAtBegin * r.worldFromObject;
        std::shared_ptr<const MotionTransform> objectFromPrimMotion;
        if (r.worldFromObjectMotion && r.worldFromObjectMotion->moving()) {
            auto moving = std::make_shared<MotionTransform>(*r.worldFromObjectMotion);
            moving->preMultiply(m_objectFromCurrentAtBegin);
            objectFromPrimMotion = std::move(moving);
        }
        r.worldFromObjectMotion.reset();
        ObjectDefinition& def = m_objects[m_objectHandle];
        const size_t bytes = recordBytes(r);
        def.bytes += bytes, m_objectBytes += bytes;
        def.pieces.push_back(
            ObjectPrim{std::move(r), objectFromPrim, std::move(objectFromPrimMotion), m_objectAttributesAtBegin});
        return;
    }
    r.solid = solidLeaf(r.loc);
    if (appendToPolygonRun(r)) return;
    m_world->primitives.push_back(std::move(r));
}

namespace {

// The "P" of a Polygon record that can join a run: its only parameter, of
// whole points, at least three; null otherwise.
const ri::Param* runnablePolygonP(const PrimitiveRecord& r) {
    if (r.type != "Polygon" || r.params.size() != 1 || !r.floatArgs.empty() || !r.intArgs.empty() ||
        !r.stringArgs.empty() || !r.shapes.empty() || r.worldFromObjectMotion)
        return nullptr;
    const ri::Param& p = r.params.params()[0];
    if (p.decl.name != "P" || p.decl.type != ri::ParamType::Point || p.decl.arraySize != 1 ||
        p.floats.size() % 3 != 0 || p.floats.size() < 9)
        return nullptr;
    return &p;
}

bool sameDecl(const ri::ParamDecl& a, const ri::ParamDecl& b) {
    return a.name == b.name && a.storage == b.storage && a.type == b.type && a.arraySize == b.arraySize &&
           a.inferred == b.inferred;
}

}  // namespace

bool Builder::appendToPolygonRun(PrimitiveRecord& r) {
    // 10^6 separate Polygon requests as 10^6 records took 1.6 KB each (the
    // record, its parameter list, the renderer's primitive); a run keeps
    // 4 bytes and the positions per polygon. Bitwise-equal transforms
    // only: the run's polygons must render exactly as separate records.
    if (m_world->primitives.empty()) return false;
    PrimitiveRecord& last = m_world->primitives.back();
    const ri::Param* p = runnablePolygonP(r);
    const ri::Param* lastP = p ? runnablePolygonP(last) : nullptr;
    if (!lastP || last.attributes != r.attributes || last.solid != r.solid || !sameDecl(lastP->decl, p->decl) ||
        std::memcmp(&last.worldFromObject, &r.worldFromObject, sizeof(Mat4)) != 0)
        return false;
    if (last.intArrays.empty()) last.intArrays.push_back({int(lastP->floats.size() / 3)});
    last.intArrays[0].push_back(int(p->floats.size() / 3));
    std::vector<float>& P = last.params.findMutable("P")->floats;
    P.insert(P.end(), p->floats.begin(), p->floats.end());
    return true;
}

void Builder::makeTexture(const std::string& picture, const std::string& texture, const std::string& swrap,
                          const std::string& twrap, const std::string& filter, float swidth, float twidth,
                          ri::ParamList params, const FileLoc& loc) {
    MakeRecord m;
    m.request = "MakeTexture";
    m.inputs = {picture};
    m.output = texture;
    m.stringArgs = {swrap, twrap, filter};
    m.floatArgs = {swidth, twidth};
    m.params = std::move(params);
    m.loc = loc;
    m_sink.make(m);
}

void Builder::makeBump(const std::string& picture, const std::string& texture, const std::string& swrap,
                       const std::string& twrap, const std::string& filter, float swidth, float twidth,
                       ri::ParamList params, const FileLoc& loc) {
    unsupported("MakeBump", loc, "MakeBump: bump maps are not supported (ignored)");
}

void Builder::makeLatLongEnvironment(const std::string& picture, const std::string& texture,
                                     const std::string& filter, float swidth, float twidth, ri::ParamList params,
                                     const FileLoc& loc) {
    MakeRecord m;
    m.request = "MakeLatLongEnvironment";
    m.inputs = {picture};
    m.output = texture;
    m.stringArgs = {filter};
    m.floatArgs = {swidth, twidth};
    m.params = std::move(params);
    m.loc = loc;
    m_sink.make(m);
}

void Builder::makeCubeFaceEnvironment(const std::array<std::string, 6>& faces, const std::string& texture,
                                      float fov, const std::string& filter, float swidth, float twidth,
                                      ri::ParamList params, const FileLoc& loc) {
    MakeRecord m;
    m.request = "MakeCubeFaceEnvironment";
    m.inputs.assign(faces.begin(), faces.end());
    m.output = texture;
    m.stringArgs = {filter};
    m.floatArgs = {fov, swidth, twidth};
    m.params = std::move(params);
    m.loc = loc;
    m_sink.make(m);
}

void Builder::makeShadow(const std::string& picture, const std::string& texture, ri::ParamList params,
                         const FileLoc& loc) {
    MakeRecord m;
    m.request = "MakeShadow";
    m.inputs = {picture};
    m.output = texture;
    m.params = std::move(params);
    m.loc = loc;
    m_sink.make(m);
}

}  // namespace umbra::scene
