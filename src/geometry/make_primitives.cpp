#include "umbra/geometry/blobby.h"
#include "umbra/geometry/curves.h"
#include "umbra/geometry/deforming.h"
#include "umbra/geometry/nupatch.h"
#include "umbra/geometry/patch.h"
#include "umbra/geometry/polygon.h"
#include "umbra/geometry/primitive.h"
#include "umbra/geometry/procedural.h"
#include "umbra/geometry/quadric.h"
#include "umbra/geometry/subdivision.h"
#include "umbra/geometry/teapot.h"

#include <numeric>
#include <optional>

namespace umbra::geometry {

namespace {

using RecordPtr = std::shared_ptr<const scene::PrimitiveRecord>;

// Elements in the position parameter (P, else Pw), or -1 without one.
long positionCount(const scene::PrimitiveRecord& rec) {
    for (const char* name : {"P", "Pw"}) {
        for (const ri::Param& p : rec.params.params())
            if (p.decl.name == name) {
                const int e = p.decl.elementSize();
                return e > 0 ? long(p.floats.size() / size_t(e)) : -1;
            }
    }
    return -1;
}

void makeQuadric(const RecordPtr& rec, Diagnostics& diag, std::vector<PrimitivePtr>& out) {
    QuadricShape shape;
    if (!Quadric::shapeFromRecord(*rec, &shape, diag)) return;
    ClassCounts counts;  // four corners of the (u, v) domain
    counts.uniform = 1;
    counts.uniformWhat = "one for the surface";
    counts.vertex = counts.varying = counts.faceVarying = 4;
    counts.vertexWhat = counts.faceVaryingWhat = "one per corner";
    auto sd = readSurfaceData(*rec, counts, false, diag);
    if (!sd) return;
    out.push_back(std::make_unique<Quadric>(rec, shape, std::move(sd)));
}

// Checks face/loop/vertex index arrays and builds the face table; npoints
// receives 1 + the largest vertex index.
std::shared_ptr<PolygonFaces> buildFaces(const scene::PrimitiveRecord& rec, const std::vector<int>* nloops,
                                         const std::vector<int>& nverts, const std::vector<int>* verts,
                                         long* npoints, Diagnostics& diag) {
    auto faces = std::make_shared<PolygonFaces>();
    const size_t nfaces = nloops ? nloops->size() : (verts ? nverts.size() : 1);
    size_t loop = 0;
    long total = 0;
    faces->faceLoopStart.push_back(0);
    faces->faceCornerStart.push_back(0);
    for (size_t f = 0; f < nfaces; ++f) {
        const long loops = nloops ? (*nloops)[f] : (verts ? 1 : long(nverts.size()));
        if (loops < 1) {
            diag.error(rec.loc, "{}: face {} has {} loops, expected at least 1", rec.type, f, loops);
            return nullptr;
        }
        if (loop + size_t(loops) > nverts.size()) {
            diag.error(rec.loc, "{}: nloops asks for {} loops, but nverts has {}", rec.type,
                       std::accumulate(nloops->begin(), nloops->end(), 0L), nverts.size());
            return nullptr;
        }
        for (long l = 0; l < loops; ++l, ++loop) {
            if (nverts[loop] < 3) {
                diag.error(rec.loc, "{}: loop {} has {} vertices, expected at least 3", rec.type, loop, nverts[loop]);
                return nullptr;
            }
            faces->loopSize.push_back(nverts[loop]);
            total += nverts[loop];
        }
        faces->faceLoopStart.push_back(int(faces->loopSize.size()));
        faces->faceCornerStart.push_back(int(total));
    }
    if (loop != nverts.size()) {
        diag.error(rec.loc, "{}: nverts has {} entries, expected {} (one per loop)", rec.type, nverts.size(), loop);
        return nullptr;
    }
    if (verts) {
        if (long(verts->size()) != total) {
            diag.error(rec.loc, "{}: vertices has {} indices, expected {} (the sum of nverts)", rec.type,
                       verts->size(), total);
            return nullptr;
        }
        long maxIndex = -1;
        for (size_t k = 0; k < verts->size(); ++k) {
            if ((*verts)[k] < 0) {
                diag.error(rec.loc, "{}: vertex index {} at position {} is negative", rec.type, (*verts)[k], k);
                return nullptr;
            }
            maxIndex = std::max(maxIndex, long((*verts)[k]));
        }
        faces->vertices = *verts;
        *npoints = maxIndex + 1;
    } else {
        faces->vertices.resize(size_t(total));
        std::iota(faces->vertices.begin(), faces->vertices.end(), 0);
        *npoints = total;
    }
    return faces;
}

// One face per polygon of a run of Polygon requests (scene::PrimitiveRecord),
// each made into the very primitives its own record would give.
void makePolygonRun(const RecordPtr& rec, Diagnostics& diag, std::vector<PrimitivePtr>& out) {
    const std::vector<int>& nverts = rec->intArrays[0];
    auto faces = std::make_shared<PolygonFaces>();
    faces->loopSize = nverts;
    faces->faceLoopStart.resize(nverts.size() + 1);
    std::iota(faces->faceLoopStart.begin(), faces->faceLoopStart.end(), 0);
    faces->faceCornerStart.assign(1, 0);
    for (int n : nverts) faces->faceCornerStart.push_back(faces->faceCornerStart.back() + n);
    const long total = faces->faceCornerStart.back();
    if (positionCount(*rec) != total) {
        diag.error(rec->loc, "Polygon: the run's \"P\" has {} vertices, expected {}", positionCount(*rec), total);
        return;
    }
    faces->vertices.resize(size_t(total));
    std::iota(faces->vertices.begin(), faces->vertices.end(), 0);
    ClassCounts counts;
    counts.uniform = nverts.size();
    counts.varying = counts.vertex = counts.faceVarying = size_t(total);
    auto sd = readSurfaceData(*rec, counts, true, diag);
    if (!sd) return;
    std::shared_ptr<const PolygonFaces> shared = std::move(faces);
    std::vector<PrimitivePtr> pieces;
    for (int f = 0; f < shared->faceCount(); ++f) {
        pieces.clear();
        appendFacePieces(rec, sd, *shared, f, pieces);
        if (pieces.size() == 1) out.push_back(std::move(pieces[0]));
        else if (!pieces.empty()) out.push_back(std::make_unique<PolygonMesh>(rec, sd, shared, f, f + 1));
    }
}

void makePolygons(const RecordPtr& rec, Diagnostics& diag, std::vector<PrimitivePtr>& out) {
    const std::string& t = rec->type;
    const auto& arrays = rec->intArrays;
    if (t == "Polygon" && arrays.size() == 1) return makePolygonRun(rec, diag, out);
    std::shared_ptr<PolygonFaces> faces;
    long npoints = 0;
    if (t == "Polygon") {
        const long n = positionCount(*rec);
        if (n < 3) {
            diag.error(rec->loc, "Polygon: expected \"P\" with at least 3 vertices, got {}", std::max(n, 0L));
            return;
        }
        faces = buildFaces(*rec, nullptr, std::vector<int>{int(n)}, nullptr, &npoints, diag);
    } else if (t == "GeneralPolygon") {
        if (arrays.size() != 1) {
            diag.error(rec->loc, "GeneralPolygon: expected 1 integer array (nverts), got {}", arrays.size());
            return;
        }
        faces = buildFaces(*rec, nullptr, arrays[0], nullptr, &npoints, diag);
    } else if (t == "PointsPolygons") {
        if (arrays.size() != 2) {
            diag.error(rec->loc, "PointsPolygons: expected 2 integer arrays (nverts vertices), got {}", arrays.size());
            return;
        }
        faces = buildFaces(*rec, nullptr, arrays[0], &arrays[1], &npoints, diag);
    } else {
        if (arrays.size() != 3) {
            diag.error(rec->loc, "PointsGeneralPolygons: expected 3 integer arrays (nloops nverts vertices), got {}",
                       arrays.size());
            return;
        }
        faces = buildFaces(*rec, &arrays[0], arrays[1], &arrays[2], &npoints, diag);
    }
    if (!faces) return;
    const bool single = t == "Polygon" || t == "GeneralPolygon";
    ClassCounts counts;
    counts.uniform = size_t(faces->faceCount());
    counts.uniformWhat = single ? "one for the polygon" : "one per face";
    counts.varying = counts.vertex = size_t(npoints);
    counts.varyingWhat = counts.vertexWhat = "one per vertex";
    counts.faceVarying = faces->vertices.size();
    counts.faceVaryingWhat = "one per face corner";
    auto sd = readSurfaceData(*rec, counts, true, diag);
    if (!sd) return;
    if (faces->faceCount() == 1) {
        // Triangles and convex quads are diceable at once; anything else
        // stays a one-face mesh until the REYES loop splits it.
        std::vector<PrimitivePtr> pieces;
        appendFacePieces(rec, sd, *faces, 0, pieces, &diag);
        if (pieces.size() == 1) {
            out.push_back(std::move(pieces[0]));
            return;
        }
        if (pieces.empty()) return;
    }
    const int nfaces = faces->faceCount();
    out.push_back(std::make_unique<PolygonMesh>(rec, std::move(sd), std::move(faces), 0, nfaces));
}

bool readWrap(const scene::PrimitiveRecord& rec, const std::string& s, const char* which, bool* periodic,
              Diagnostics& diag) {
    if (s == "periodic") *periodic = true;
    else if (s == "nonperiodic") *periodic = false;
    else {
        diag.error(rec.loc, "PatchMesh: {} must be \"periodic\" or \"nonperiodic\", got \"{}\"", which, s);
        return false;
    }
    return true;
}

// Attribute "umbra" "patchblock": the most patches along each side of a
// block of a bicubic PatchMesh diced as one grid (BicubicBlock); 0 or 1
// dices patch by patch.
constexpr int kDefaultPatchBlock = 8;

int patchBlockSide(const scene::PrimitiveRecord& rec) {
    if (!rec.attributes) return kDefaultPatchBlock;
    auto it = rec.attributes->user.find("umbra:patchblock");
    if (it == rec.attributes->user.end()) return kDefaultPatchBlock;
    const ri::Param& p = it->second;
    if (!p.ints.empty()) return p.ints[0];
    if (!p.floats.empty()) return int(p.floats[0]);
    return kDefaultPatchBlock;
}

// True when the record carries a class a patch block cannot interpolate
// (BicubicPatchArray::blockable), read from its parameters alone.
bool hasPerPatchClasses(const scene::PrimitiveRecord& rec) {
    for (const ri::Param& p : rec.params.params())
        if (p.decl.storage == ri::StorageClass::Uniform || p.decl.storage == ri::StorageClass::FaceVarying ||
            p.decl.storage == ri::StorageClass::FaceVertex)
            return true;
    return false;
}

// `blockSide` < 0: the record's own patchblock attribute.
void makePatches(const RecordPtr& rec, Diagnostics& diag, std::vector<PrimitivePtr>& out, int blockSide = -1) {
    const bool mesh = rec->type == "PatchMesh";
    const auto& sa = rec->stringArgs;
    if (sa.size() != (mesh ? 3u : 1u)) {
        if (mesh) diag.error(rec->loc, "PatchMesh: expected 3 string arguments (type uwrap vwrap), got {}", sa.size());
        else diag.error(rec->loc, "Patch: expected 1 string argument (type), got {}", sa.size());
        return;
    }
    if (sa[0] != "bilinear" && sa[0] != "bicubic") {
        diag.error(rec->loc, "{}: type must be \"bilinear\" or \"bicubic\", got \"{}\"", rec->type, sa[0]);
        return;
    }
    const bool bicubic = sa[0] == "bicubic";
    const scene::Basis uBasis = rec->attributes ? rec->attributes->uBasis : scene::Basis::bezier();
    const scene::Basis vBasis = rec->attributes ? rec->attributes->vBasis : scene::Basis::bezier();
    int nu = bicubic ? 4 : 2, nv = nu;
    bool uper = false, vper = false;
    if (mesh) {
        if (rec->intArgs.size() != 2) {
            diag.error(rec->loc, "PatchMesh: expected 2 integer arguments (nu nv), got {}", rec->intArgs.size());
            return;
        }
        nu = rec->intArgs[0];
        nv = rec->intArgs[1];
        if (!readWrap(*rec, sa[1], "uwrap", &uper, diag) || !readWrap(*rec, sa[2], "vwrap", &vper, diag)) return;
    }
    // Patches along one direction (RI spec 3.2 §5.5, PatchMesh).
    auto patchCount = [&](int n, bool periodic, int step, const char* dir) -> int {
        if (!bicubic) {
            if (n < (periodic ? 1 : 2)) {
                diag.error(rec->loc, "PatchMesh: n{} is {}, expected at least {} for a {} bilinear mesh", dir, n,
                           periodic ? 1 : 2, periodic ? "periodic" : "nonperiodic");
                return 0;
            }
            return periodic ? n : n - 1;
        }
        if (step < 1) step = 1;
        if (periodic ? (n < step || n % step != 0) : (n < 4 || (n - 4) % step != 0)) {
            diag.error(rec->loc, "PatchMesh: n{} is {}, expected {} for a {} bicubic mesh with {}step {}", dir, n,
                       periodic ? "a positive multiple of the step" : "4 plus a multiple of the step",
                       periodic ? "periodic" : "nonperiodic", dir, step);
            return 0;
        }
        return periodic ? n / step : (n - 4) / step + 1;
    };
    const int ustep = uBasis.step, vstep = vBasis.step;
    const int nup = patchCount(nu, uper, ustep, "u");
    if (nup == 0) return;
    const int nvp = patchCount(nv, vper, vstep, "v");
    if (nvp == 0) return;
    const int nuvary = uper ? nup : nup + 1, nvvary = vper ? nvp : nvp + 1;

    ClassCounts counts;
    counts.uniform = size_t(nup) * size_t(nvp);
    counts.uniformWhat = mesh ? "one per patch" : "one for the patch";
    counts.varying = size_t(nuvary) * size_t(nvvary);
    counts.varyingWhat = "one per patch corner";
    counts.vertex = size_t(nu) * size_t(nv);
    counts.vertexWhat = "one per control vertex";
    counts.faceVarying = 4 * counts.uniform;
    counts.faceVaryingWhat = "four per patch";
    auto sd = readSurfaceData(*rec, counts, true, diag, true, nu, nv, uper, vper);
    if (!sd) return;

    // Bicubic meshes of more than one patch go out as blocks of patches,
    // each diced as one grid, when every variable can ride on such a grid.
    std::shared_ptr<BicubicPatchArray> blocks;
    if (blockSide < 0) blockSide = patchBlockSide(*rec);
    if (bicubic && blockSide > 1 && nup * nvp > 1 && BicubicPatchArray::blockable(*sd)) {
        blocks = std::make_shared<BicubicPatchArray>();
        blocks->sd = sd;
        blocks->columns = nup;
        blocks->rows = nvp;
        blocks->uScale = 1.0f / float(nup);
        blocks->vScale = 1.0f / float(nvp);
        blocks->coeffs.reserve(size_t(nup) * size_t(nvp));
        blocks->refs.reserve(size_t(nup) * size_t(nvp));
        blocks->bounds.reserve(size_t(nup) * size_t(nvp));
    }
    for (int pj = 0; pj < nvp; ++pj)
        for (int pi = 0; pi < nup; ++pi) {
            CornerRefs refs;
            const int patch = pj * nup + pi;
            for (int c = 0; c < 4; ++c) {
                const int du = c & 1, dv = c >> 1;
                refs.varying[c] = ((pj + dv) % nvvary) * nuvary + (pi + du) % nuvary;
                refs.vertex[c] = ((pj + dv) % nv) * nu + (pi + du) % nu;
                refs.faceVarying[c] = 4 * patch + c;
            }
            refs.uniform = patch;
            // u, v run over [0, 1] across the whole mesh, patch by patch.
            ParamMap map{float(pi) / float(nup), 1.0f / float(nup), float(pj) / float(nvp), 1.0f / float(nvp)};
            if (!bicubic) {
                out.push_back(std::make_unique<BilinearPatch>(rec, sd, refs, ParamRange{}, map));
                continue;
            }
            std::array<int, 16> ctrl;
            for (int j = 0; j < 4; ++j)
                for (int i = 0; i < 4; ++i)
                    ctrl[size_t(j * 4 + i)] = ((pj * vstep + j) % nv) * nu + (pi * ustep + i) % nu;
            auto coeffs = BicubicCoeffs::make(*sd, ctrl, uBasis, vBasis);
            if (blocks) {
                blocks->bounds.push_back(bicubicHullBound(*coeffs, ParamRange{}));
                blocks->coeffs.push_back(std::move(coeffs));
                blocks->refs.push_back(refs);
                continue;
            }
            out.push_back(std::make_unique<BicubicPatch>(rec, sd, std::move(coeffs), refs, ParamRange{}, map));
        }
    if (blocks) BicubicBlock::appendBlocks(rec, std::move(blocks), blockSide, out);
}

/// `Geometry "teapot"`: the Newell teapot's Bezier patches, whatever the
/// current Basis (the patches are Bezier data).
void makeTeapot(const RecordPtr& rec, Diagnostics& diag, std::vector<PrimitivePtr>& out) {
    auto attrs = std::make_shared<scene::Attributes>(rec->attributes ? *rec->attributes : scene::Attributes());
    attrs->uBasis = attrs->vBasis = scene::Basis::bezier();
    for (int patch = 0; patch < kTeapotPatchCount; ++patch) {
        auto piece = std::make_shared<scene::PrimitiveRecord>(rec->derived("Patch"));
        piece->attributes = attrs;
        piece->stringArgs = {"bicubic"};
        ri::Param P;
        P.decl.name = "P";
        P.decl.storage = ri::StorageClass::Vertex;
        P.decl.type = ri::ParamType::Point;
        P.loc = rec->loc;
        for (int k = 0; k < 16; ++k) {
            const Vec3 c = teapotControlPoint(patch, k);
            P.floats.insert(P.floats.end(), {c.x, c.y, c.z});
        }
        piece->params.add(std::move(P));
        makePatches(piece, diag, out);
    }
}

}  // namespace

namespace {

std::vector<PrimitivePtr> makeShape(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                                    int blockSide = -1, const ParameterReaders* readers = nullptr);

/// A deforming primitive (MotionBegin around it): one primitive per shape,
/// paired up. Shapes whose requests make a different number of primitives
/// than the first are malformed: the first shape renders alone.
std::vector<PrimitivePtr> makeDeforming(const RecordPtr& record, Diagnostics& diag, const ParameterReaders* readers) {
    // Every shape must split into the same pieces: patch blocks of the
    // first shape's size, and only when no shape carries a class that
    // would make its mesh patch by patch.
    int blockSide = patchBlockSide(*record);
    for (const scene::PrimitiveRecord& s : record->shapes)
        if (hasPerPatchClasses(s)) blockSide = 0;
    if (hasPerPatchClasses(*record)) blockSide = 0;
    // The shaders are the first shape's: every shape gets its answer,
    // asked once and only by a family that asks (subdivision meshes).
    ParameterReaders firstShapes;
    std::optional<bool> reads;
    if (readers) {
        firstShapes = [&reads, ask = readers, &record](const scene::Attributes&) {
            if (!reads) reads = (*ask)(record->attributes ? *record->attributes : scene::Attributes());
            return *reads;
        };
        readers = &firstShapes;
    }
    std::vector<std::vector<PrimitivePtr>> shapes;
    if (record->type == "Blobby") {
        // Each shape polygonised on its own would not pair up: the first
        // shape's triangles are carried to the others.
        std::vector<PrimitivePtr> out;
        makeDeformingBlobby(record, diag, out);
        return out;
    }
    shapes.push_back(makeShape(record, diag, blockSide, readers));
    for (const scene::PrimitiveRecord& s : record->shapes) {
        shapes.push_back(makeShape(std::make_shared<const scene::PrimitiveRecord>(s), diag, blockSide, readers));
        if (shapes.back().size() != shapes[0].size()) {
            diag.error(s.loc, "{}: this motion shape makes {} primitives where the first makes {} (the primitive "
                       "renders unblurred)", s.type, shapes.back().size(), shapes[0].size());
            return std::move(shapes[0]);
        }
    }
    std::vector<PrimitivePtr> out;
    for (size_t i = 0; i < shapes[0].size(); ++i) {
        std::vector<PrimitivePtr> keyed;
        for (auto& s : shapes) keyed.push_back(std::move(s[i]));
        out.push_back(std::make_unique<DeformingPrimitive>(std::move(keyed)));
    }
    return out;
}

}  // namespace

namespace {

std::vector<PrimitivePtr> makeAll(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                                  const ParameterReaders* readers) {
    if (record && !record->shapes.empty()) return makeDeforming(record, diag, readers);
    return makeShape(std::move(record), diag, -1, readers);
}

}  // namespace

std::vector<PrimitivePtr> makePrimitives(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag) {
    return makeAll(std::move(record), diag, nullptr);
}

std::vector<PrimitivePtr> makePrimitives(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                                         const std::shared_ptr<ProceduralContext>& procedurals,
                                         const ParameterReaders& readers) {
    if (!record || !isProceduralRecord(*record)) return makeAll(std::move(record), diag, readers ? &readers : nullptr);
    std::vector<PrimitivePtr> out;
    if (!record->shapes.empty())
        diag.warningOnce("procedural:motion", record->loc, "Procedural: a MotionBegin block around a procedural is "
                         "not supported; its first shape is expanded");
    if (procedurals)
        out.push_back(std::make_unique<Procedural>(std::move(record), procedurals));
    else
        diag.warningOnce("procedural:nocontext", record->loc, "Procedural: expanded only when rendering (skipped)");
    return out;
}

namespace {

std::vector<PrimitivePtr> makeShape(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                                    int blockSide, const ParameterReaders* readers) {
    std::vector<PrimitivePtr> out;
    if (!record) return out;
    const std::string& t = record->type;
    if (t == "Sphere" || t == "Cylinder" || t == "Cone" || t == "Disk" || t == "Paraboloid" || t == "Hyperboloid" ||
        t == "Torus")
        makeQuadric(record, diag, out);
    else if (t == "Polygon" || t == "GeneralPolygon" || t == "PointsPolygons" || t == "PointsGeneralPolygons")
        makePolygons(record, diag, out);
    else if (t == "Patch" || t == "PatchMesh")
        makePatches(record, diag, out, blockSide);
    else if (t == "SubdivisionMesh" || t == "HierarchicalSubdivisionMesh")
    {
        // Regular regions as blocks of the patchblock side, where no shader
        // can tell the blocks' u, v from the faces'.
        const int side = blockSide < 0 ? patchBlockSide(*record) : blockSide;
        const bool blocks = side > 1 && readers &&
                            !(*readers)(record->attributes ? *record->attributes : scene::Attributes());
        makeSubdivisionMesh(record, diag, out, blocks ? side : 0);
    }
    else if (t == "NuPatch")
        makeNuPatches(record, diag, out);
    else if (t == "Curves")
        makeCurves(record, diag, out);
    else if (t == "Points")
        makePoints(record, diag, out);
    else if (t == "Blobby")
        makeBlobby(record, diag, out);
    else if (t == "Geometry" && !record->stringArgs.empty() && record->stringArgs[0] == "teapot")
        makeTeapot(record, diag, out);
    else
        diag.warningOnce("geometry:unsupported:" + t, record->loc, "{}: primitive type not supported yet; ignored", t);
    return out;
}

}  // namespace

}  // namespace umbra::geometry
