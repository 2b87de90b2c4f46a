#pragma once
// Internal to the render module: whether an automatic depth map of an
// earlier frame can stand in for this frame's. The decision is made from
// content, never from file times: digests of what the depth passes read
// (the light's view, the map's settings, every caster record), compared
// part by part so the statistics can say what changed (docs/shadows.md,
// "Maps reused across frames").

#include "umbra/scene/scene.h"

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace umbra::render {

/// A 128-bit content digest (FNV-1a over 128 bits). Equal content gives
/// equal digests on every machine; a chance collision is ~2^-64 for a
/// billion digests.
struct Digest {
    uint64_t hi = 0, lo = 0;
    bool operator==(const Digest&) const = default;
    std::string hex() const;
};

/// Feeds values into a Digest. Every variable-length value is preceded by
/// its length, so ("ab", "c") and ("a", "bc") differ.
class Hasher {
public:
    Hasher& bytes(const void* data, size_t size);
    Hasher& u64(uint64_t v) { return bytes(&v, sizeof v); }
    Hasher& i32(int v) { return bytes(&v, sizeof v); }
    Hasher& f32(float v) { return bytes(&v, sizeof v); }
    Hasher& flag(bool v) { return i32(v ? 1 : 0); }
    Hasher& str(std::string_view s);
    Hasher& floats(const std::vector<float>& v);
    Hasher& ints(const std::vector<int>& v);
    Hasher& strings(const std::vector<std::string>& v);
    Hasher& matrix(const Mat4& m);
    Hasher& digest(const Digest& d) { return u64(d.hi).u64(d.lo); }
    Digest value() const { return {uint64_t(m_state >> 64), uint64_t(m_state)}; }

private:
    // FNV-1a 128-bit offset basis.
    unsigned __int128 m_state = (unsigned __int128)0x6c62272e07bb0142ULL << 64 | 0x62b821756295c58dULL;
};

/// Everything that decides an automatic map's texels, in parts that name
/// a reason when they differ.
struct MapContent {
    int size = 0;             // the map's resolution (square)
    Digest settings;          // depth filter, culling, dicing rates, sampling options
    Digest view;              // the light's shader and the depth passes' cameras
    std::vector<Digest> casters;  // each shadow-casting primitive record, in scene order
    /// The frame's random seed when the passes depend on the frame (motion
    /// blur draws sample times from it; a displacement shader may call
    /// random() or option(): Shader::variesByFrame).
    std::optional<uint32_t> seed;
};

/// The digest of one caster: its geometry, transforms (motion included)
/// and the attributes a depth pass reads (displacement and its shader
/// parameters, sides, orientation, dicing, visibility, ...).
Digest casterDigest(const scene::PrimitiveRecord& record);

/// Why `now` may or may not reuse the map made for `before` (null: there
/// is none): "same content" (reusable), or the first difference found:
/// "first frame", "map size changed", "map settings changed", "new caster",
/// "caster removed", "caster changed", "casters reordered", "light changed",
/// "frame seed changed". Casters come before the light: a distant light's
/// view is fitted to its casters, so a moved caster moves it too.
std::string reuseReason(const MapContent* before, const MapContent& now);

/// The one digest naming a map's content in a map cache shared between
/// processes (`umbra render --map-cache DIR`): every part of `content`
/// and umbra's version, so a map made by another release is not taken.
/// Null for a map drawing on the frame's seed: such maps are never shared.
std::optional<Digest> cacheDigest(const MapContent& content);

/// The reason reuseReason gives when the map can be reused.
inline constexpr std::string_view kSameContent = "same content";

}  // namespace umbra::render
