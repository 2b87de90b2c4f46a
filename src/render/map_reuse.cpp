#include "render/map_reuse.h"

#include <fmt/format.h>

#include <algorithm>

namespace umbra::render {

namespace {

// FNV-1a 128-bit prime: 2^88 + 2^8 + 0x3b.
const unsigned __int128 kFnvPrime = (unsigned __int128)1 << 88 | 0x13b;

void hashParams(Hasher& h, const ri::ParamList& params) {
    h.u64(params.size());
    for (const ri::Param& p : params.params()) {
        h.str(p.decl.name).i32(int(p.decl.storage)).i32(int(p.decl.type)).i32(p.decl.arraySize);
        h.floats(p.floats).ints(p.ints).strings(p.strings);
    }
}

void hashShader(Hasher& h, const std::shared_ptr<const scene::ShaderRecord>& shader) {
    h.flag(bool(shader));
    if (!shader) return;
    h.str(shader->name).matrix(shader->worldFromShader);
    hashParams(h, shader->params);
}

void hashBasis(Hasher& h, const scene::Basis& b) {
    h.bytes(b.m, sizeof b.m).i32(b.step);
}

/// A moving transform by its values at every key time and halfway
/// between: two transforms equal there move alike.
void hashMotion(Hasher& h, const std::shared_ptr<const MotionTransform>& motion) {
    h.flag(motion && motion->moving());
    if (!motion || !motion->moving()) return;
    const std::vector<float> times = motion->keyTimes();
    h.floats(times);
    for (size_t i = 0; i < times.size(); ++i) {
        h.matrix(motion->at(times[i]));
        if (i + 1 < times.size()) h.matrix(motion->at(0.5f * (times[i] + times[i + 1])));
    }
}

/// What a depth pass reads of a primitive's attributes. Surface shading,
/// colour (unless a displacement shader may read it), light lists and
/// names do not reach a depth map, so changing them keeps the map.
void hashAttributes(Hasher& h, const scene::Attributes& a) {
    h.f32(a.shadingRate).i32(a.sides).flag(a.insideOut).flag(a.matte);
    hashShader(h, a.displacement);
    if (a.displacement) {
        h.bytes(&a.color, sizeof a.color).bytes(&a.opacity, sizeof a.opacity);
        h.bytes(a.textureCoordinates, sizeof a.textureCoordinates);
    }
    h.f32(a.displacementBound).str(a.displacementBoundSpace);
    hashBasis(h, a.uBasis);
    hashBasis(h, a.vBasis);
    h.str(a.solid).flag(a.castsShadows).flag(a.binaryDice);
    h.flag(bool(a.trimCurves));
    if (a.trimCurves) {
        const scene::TrimCurveRecord& t = *a.trimCurves;
        h.ints(t.ncurves).ints(t.order).ints(t.n);
        h.floats(t.knot).floats(t.min).floats(t.max).floats(t.u).floats(t.v).floats(t.w);
    }
    // Attributes of umbra's own and the user's ("dice:...", "umbra:..."):
    // any of them may steer dicing.
    h.u64(a.user.size());
    for (const auto& [name, p] : a.user) h.str(name).floats(p.floats).ints(p.ints).strings(p.strings);
    h.u64(a.scopedSpaces.size());  // a displacement's spaces
    for (const auto& [name, m] : a.scopedSpaces) h.str(name).matrix(m);
}

void hashRecord(Hasher& h, const scene::PrimitiveRecord& r) {
    h.str(r.type).floats(r.floatArgs).ints(r.intArgs).strings(r.stringArgs);
    h.u64(r.intArrays.size());
    for (const auto& a : r.intArrays) h.ints(a);
    hashParams(h, r.params);
    h.matrix(r.worldFromObject);
    hashMotion(h, r.worldFromObjectMotion);
    h.floats(r.shapeTimes);
    h.u64(r.shapes.size());
    for (const auto& shape : r.shapes) hashRecord(h, shape);
}

}  // namespace

std::string Digest::hex() const { return fmt::format("{:016x}{:016x}", hi, lo); }

Hasher& Hasher::bytes(const void* data, size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < size; ++i) {
        m_state ^= p[i];
        m_state *= kFnvPrime;
    }
    return *this;
}

Hasher& Hasher::str(std::string_view s) {
    u64(s.size());
    return bytes(s.data(), s.size());
}

Hasher& Hasher::floats(const std::vector<float>& v) {
    u64(v.size());
    return bytes(v.data(), v.size() * sizeof(float));
}

Hasher& Hasher::ints(const std::vector<int>& v) {
    u64(v.size());
    return bytes(v.data(), v.size() * sizeof(int));
}

Hasher& Hasher::strings(const std::vector<std::string>& v) {
    u64(v.size());
    for (const auto& s : v) str(s);
    return *this;
}

Hasher& Hasher::matrix(const Mat4& m) { return bytes(m.m, sizeof m.m); }

Digest casterDigest(const scene::PrimitiveRecord& record) {
    Hasher h;
    hashRecord(h, record);
    h.flag(bool(record.attributes));
    if (record.attributes) hashAttributes(h, *record.attributes);
    return h.value();
}

std::string reuseReason(const MapContent* before, const MapContent& now) {
    if (!before) return "first frame";
    if (before->size != now.size) return "map size changed";
    if (!(before->settings == now.settings)) return "map settings changed";
    // A caster the earlier frame did not have (by content) is a new one
    // when the count grew; one it had and this frame lacks, a removed one.
    auto missingFrom = [](const std::vector<Digest>& a, const std::vector<Digest>& b) {
        std::vector<Digest> sorted = b;
        auto less = [](const Digest& x, const Digest& y) { return x.hi != y.hi ? x.hi < y.hi : x.lo < y.lo; };
        std::sort(sorted.begin(), sorted.end(), less);
        for (const Digest& d : a)
            if (!std::binary_search(sorted.begin(), sorted.end(), d, less)) return true;
        return false;
    };
    if (now.casters.size() > before->casters.size()) return "new caster";
    if (now.casters.size() < before->casters.size()) return "caster removed";
    if (now.casters != before->casters) return missingFrom(now.casters, before->casters) ? "caster changed" : "casters reordered";
    if (!(before->view == now.view)) return "light changed";
    if (before->seed != now.seed) return "frame seed changed";
    return std::string(kSameContent);
}

}  // namespace umbra::render

namespace umbra::render {

std::optional<Digest> cacheDigest(const MapContent& content) {
    if (content.seed) return std::nullopt;
    // The release and the cache's layout: a map another umbra made (whose
    // depth passes may differ) is another map.
    Hasher h;
    h.str("umbra 0.1.0 map cache 1").i32(content.size).digest(content.settings).digest(content.view);
    h.u64(content.casters.size());
    for (const Digest& d : content.casters) h.digest(d);
    return h.value();
}

}  // namespace umbra::render
