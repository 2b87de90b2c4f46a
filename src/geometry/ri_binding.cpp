// The C binding a DynamicLoad DSO calls (include/umbra/geometry/ri.h):
// each call becomes the ri::Target request its RIB form would, on the
// expansion this thread is running.

#include "umbra/geometry/ri.h"

#include "geometry/ri_binding.h"
#include "umbra/ri/declarations.h"

#include <cstdarg>
#include <cstdlib>
#include <memory>
#include <vector>

namespace umbra::geometry {

namespace {

struct Callbacks {
    ri::Target* target = nullptr;
    Diagnostics* diag = nullptr;
    FileLoc loc;
    ri::Declarations declarations;
};

thread_local Callbacks* t_callbacks = nullptr;

/// Elements a parameter of each storage class has on one primitive.
struct ClassCounts {
    size_t uniform = 1, varying = 1, vertex = 1;
};

/// A C parameter list as a ParamList: each value array is read by its
/// token's declaration, with as many elements as its class has.
ri::ParamList paramList(const char* request, RtInt n, RtToken tokens[], RtPointer values[], ClassCounts counts) {
    Callbacks& cb = *t_callbacks;
    ri::ParamList list;
    for (RtInt i = 0; i < n; ++i) {
        ri::Param p;
        std::string error;
        if (!tokens[i] || !values[i] || !cb.declarations.resolve(tokens[i], &p.decl, &error)) {
            cb.diag->warning(cb.loc, "{}: parameter \"{}\" from the DSO: {} (ignored)", request,
                             tokens[i] ? tokens[i] : "(null)", error.empty() ? "no value" : error);
            continue;
        }
        size_t elements = 1;
        switch (p.decl.storage) {
        case ri::StorageClass::Constant: elements = 1; break;
        case ri::StorageClass::Uniform: elements = counts.uniform; break;
        case ri::StorageClass::Vertex: elements = counts.vertex; break;
        default: elements = counts.varying; break;
        }
        const size_t values_ = elements * size_t(p.decl.elementSize());
        if (ri::isFloatType(p.decl.type)) {
            const float* v = static_cast<const float*>(values[i]);
            p.floats.assign(v, v + values_);
        } else if (p.decl.type == ri::ParamType::String) {
            char* const* v = static_cast<char* const*>(values[i]);
            for (size_t k = 0; k < values_; ++k) p.strings.emplace_back(v[k] ? v[k] : "");
        } else {
            const int* v = static_cast<const int*>(values[i]);
            p.ints.assign(v, v + values_);
        }
        p.loc = cb.loc;
        list.add(std::move(p));
    }
    return list;
}

/// The token/value pairs of a variadic call, up to RI_NULL.
void collect(va_list ap, std::vector<RtToken>& tokens, std::vector<RtPointer>& values) {
    for (RtToken t = va_arg(ap, RtToken); t; t = va_arg(ap, RtToken)) {
        tokens.push_back(t);
        values.push_back(va_arg(ap, RtPointer));
    }
}

ri::Target* target() { return t_callbacks ? t_callbacks->target : nullptr; }
const FileLoc& loc() { return t_callbacks->loc; }

}  // namespace

RiCallbackScope::RiCallbackScope(ri::Target& target, Diagnostics& diag, const FileLoc& loc) {
    t_callbacks = new Callbacks{&target, &diag, loc, {}};
}

RiCallbackScope::~RiCallbackScope() {
    delete t_callbacks;
    t_callbacks = nullptr;
}

}  // namespace umbra::geometry

using namespace umbra;
using umbra::geometry::target;

extern "C" {

RtVoid RiAttributeBegin(void) {
    if (auto* t = target()) t->attributeBegin(geometry::loc());
}
RtVoid RiAttributeEnd(void) {
    if (auto* t = target()) t->attributeEnd(geometry::loc());
}
RtVoid RiTransformBegin(void) {
    if (auto* t = target()) t->transformBegin(geometry::loc());
}
RtVoid RiTransformEnd(void) {
    if (auto* t = target()) t->transformEnd(geometry::loc());
}
RtVoid RiColor(RtColor c) {
    if (auto* t = target()) t->color({c[0], c[1], c[2]}, geometry::loc());
}
RtVoid RiOpacity(RtColor c) {
    if (auto* t = target()) t->opacity({c[0], c[1], c[2]}, geometry::loc());
}
RtVoid RiTranslate(RtFloat dx, RtFloat dy, RtFloat dz) {
    if (auto* t = target()) t->translate({dx, dy, dz}, geometry::loc());
}
RtVoid RiRotate(RtFloat angle, RtFloat dx, RtFloat dy, RtFloat dz) {
    if (auto* t = target()) t->rotate(angle, {dx, dy, dz}, geometry::loc());
}
RtVoid RiScale(RtFloat sx, RtFloat sy, RtFloat sz) {
    if (auto* t = target()) t->scale({sx, sy, sz}, geometry::loc());
}
RtVoid RiConcatTransform(RtMatrix m) {
    if (auto* t = target()) t->concatTransform(Mat4::fromRib(&m[0][0]), geometry::loc());
}

RtVoid RiSurfaceV(RtToken name, RtInt n, RtToken tokens[], RtPointer values[]) {
    if (auto* t = target()) t->surface(name ? name : "", geometry::paramList("Surface", n, tokens, values, {}), geometry::loc());
}
RtVoid RiSurface(RtToken name, ...) {
    std::vector<RtToken> tokens;
    std::vector<RtPointer> values;
    va_list ap;
    va_start(ap, name);
    geometry::collect(ap, tokens, values);
    va_end(ap);
    RiSurfaceV(name, RtInt(tokens.size()), tokens.data(), values.data());
}

RtVoid RiSphereV(RtFloat radius, RtFloat zmin, RtFloat zmax, RtFloat thetamax, RtInt n, RtToken tokens[],
                 RtPointer values[]) {
    auto* t = target();
    if (!t) return;
    ri::RequestArgs args;
    args.floats = {radius, zmin, zmax, thetamax};
    t->primitive("Sphere", std::move(args), geometry::paramList("Sphere", n, tokens, values, {1, 4, 4}),
                 geometry::loc());
}
RtVoid RiSphere(RtFloat radius, RtFloat zmin, RtFloat zmax, RtFloat thetamax, ...) {
    std::vector<RtToken> tokens;
    std::vector<RtPointer> values;
    va_list ap;
    va_start(ap, thetamax);
    geometry::collect(ap, tokens, values);
    va_end(ap);
    RiSphereV(radius, zmin, zmax, thetamax, RtInt(tokens.size()), tokens.data(), values.data());
}

RtVoid RiPolygonV(RtInt nvertices, RtInt n, RtToken tokens[], RtPointer values[]) {
    auto* t = target();
    if (!t || nvertices < 0) return;
    const size_t nv = size_t(nvertices);
    t->primitive("Polygon", {}, geometry::paramList("Polygon", n, tokens, values, {1, nv, nv}), geometry::loc());
}
RtVoid RiPolygon(RtInt nvertices, ...) {
    std::vector<RtToken> tokens;
    std::vector<RtPointer> values;
    va_list ap;
    va_start(ap, nvertices);
    geometry::collect(ap, tokens, values);
    va_end(ap);
    RiPolygonV(nvertices, RtInt(tokens.size()), tokens.data(), values.data());
}

RtVoid RiProcedural(RtPointer data, RtBound bound, RtProcSubdivFunc subdivfunc, RtProcFreeFunc freefunc) {
    auto* t = target();
    if (!t) return;
    ri::RequestArgs args;
    args.floats.assign(bound, bound + 6);
    RtString* strings = static_cast<RtString*>(data);
    size_t count = 0;
    if (subdivfunc == RiProcDelayedReadArchive) {
        args.strings = {"DelayedReadArchive"};
        count = 1;
    } else if (subdivfunc == RiProcRunProgram) {
        args.strings = {"RunProgram"};
        count = 2;
    } else if (subdivfunc == RiProcDynamicLoad) {
        args.strings = {"DynamicLoad"};
        count = 2;
    } else {
        geometry::t_callbacks->diag->warning(geometry::loc(), "RiProcedural: a DSO's own subdivide function is not "
                                             "supported (only RiProcDelayedReadArchive, RiProcRunProgram and "
                                             "RiProcDynamicLoad); skipped");
    }
    for (size_t i = 0; i < count; ++i) args.strings.emplace_back(strings && strings[i] ? strings[i] : "");
    if (count) t->primitive("Procedural", std::move(args), {}, geometry::loc());
    if (freefunc) freefunc(data);
}

// Markers for RiProcedural: umbra expands these procedurals itself.
RtVoid RiProcDelayedReadArchive(RtPointer, RtFloat) {}
RtVoid RiProcRunProgram(RtPointer, RtFloat) {}
RtVoid RiProcDynamicLoad(RtPointer, RtFloat) {}
// The RI spec's: the data was malloc'ed by the DSO.
RtVoid RiProcFree(RtPointer data) { std::free(data); }

}  // extern "C"
