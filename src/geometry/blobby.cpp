#include "umbra/geometry/blobby.h"

#include "umbra/geometry/deforming.h"
#include "umbra/shadow/depth_image.h"

#include <fmt/format.h>

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <unordered_map>

namespace umbra::geometry {

/// A repelling plane (opcode 1003): the depth map, read once per Blobby,
/// how the Blobby's object space maps onto it, and Application Note #31's
/// parameters A (cut-off height), B (the barrier's strength), C (height of
/// the bulge's peak) and D (the bulge's value there); heights are in the
/// map's camera-space units.
struct BlobbyField::Plane {
    std::shared_ptr<const DepthImage> map;
    Mat4 ndcFromObject;    // the map's worldToNDC after the Blobby's transform (projective)
    Mat4 lightFromObject;  // the map's worldToCamera after it (affine)
    float cutoff = 1, barrier = 0, bulgeHeight = 1, bulge = 0;

    /// The leaf's field at object-space `p`; with `gradient`, its gradient.
    float value(const Vec3& p, Vec3* gradient) const;
};

namespace {

// Application Note #31's field of a repelling plane at height z above the
// surface in its map, with the derivative in z in *dz:
//   (D bump(z/C) - B/z) (1 - ease(z/A)) for z < A, 0 from A up,
// where bump(r) = r^3 (2 - r)^3 on [0, 2] (0 with two zero derivatives at
// both ends, 1 at r = 1) and ease(r) = r^2 (3 - 2r) on [0, 1]. Heights
// below 1e-6 (points at or under the surface) count as 1e-6, the note's
// ZCLAMP.
float repulsion(float z, float A, float B, float C, float D, float* dz) {
    *dz = 0;
    if (z >= A) return 0;
    const bool clamped = z <= 1e-6f;
    if (clamped) z = 1e-6f;
    const float r = z / C;
    float bump = 0, dbump = 0;
    if (r > 0 && r < 2) {
        const float q = r * (2 - r);
        bump = q * q * q;
        dbump = 3 * q * q * (2 - 2 * r) / C;
    }
    const float e = std::min(z / A, 1.0f);
    const float ease = e * e * (3 - 2 * e), dease = 6 * e * (1 - e) / A;
    const float f = D * bump - B / z;
    if (!clamped) *dz = (D * dbump + B / (z * z)) * (1 - ease) - f * dease;
    return f * (1 - ease);
}

// A repelling plane's depth map, read whole. Blobbies naming the same
// unchanged file (same device, inode, size and modification time: a map
// written again, atomically, is a new inode) share one copy while any of
// them holds it, so a thousand droplets over one ground read it once.
// Null when it cannot be read (the reasons in `reading`).
std::shared_ptr<const DepthImage> readPlaneMap(const std::string& name, Diagnostics& reading) {
    static std::mutex mutex;
    static std::map<std::string, std::weak_ptr<const DepthImage>> shared;
    struct stat st {};
    std::string key;
    if (::stat(name.c_str(), &st) == 0)
        key = fmt::format("{}:{}:{}:{}.{}", st.st_dev, st.st_ino, st.st_size, st.st_mtim.tv_sec, st.st_mtim.tv_nsec);
    if (!key.empty()) {
        std::lock_guard<std::mutex> lock(mutex);
        if (auto hit = shared[key].lock()) return hit;
    }
    auto image = std::make_shared<DepthImage>();
    if (!readDepthFile(name, *image, reading)) return nullptr;
    if (!key.empty()) {
        std::lock_guard<std::mutex> lock(mutex);
        for (auto it = shared.begin(); it != shared.end();) it = it->second.expired() ? shared.erase(it) : ++it;
        shared[key] = image;
    }
    return image;
}

using Op = BlobbyField::Op;

// The smallest share of its coarse triangle's (u, v) domain a piece may
// have before split() drops it instead (16 halvings: a 1/256 of the
// triangle's edge, under a pixel unless one triangle spans hundreds of
// pixels). A field divided by a thin leaf jumps where the divisor's
// support ends, and pieces across the jump never shrink on screen: at 24
// halvings one such Blobby took 396,000 splits.
constexpr float kMinPieceArea = 1.0f / float(1 << 16);

// A leaf's field at squared unit distance r2: 1 at the centre, falling to 0
// with zero slope and curvature at r2 = 1 (Aqsis's 1 - 3r2 + 3r2^2 - r2^3).
// Smallest singular value of M's 3x3 part, from below: 1 / |inverse|_F.
float smallestScale(const Mat4& inverse) {
    double f = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) f += double(inverse.m[i][j]) * inverse.m[i][j];
    return f > 0 ? float(1 / std::sqrt(f)) : 0;
}

Vec3 nearestOnSegment(const Vec3& q, const Vec3& a, const Vec3& b) {
    const Vec3 ab = b - a;
    const float len2 = dot(ab, ab);
    const float t = len2 > 0 ? std::clamp(dot(q - a, ab) / len2, 0.0f, 1.0f) : 0.0f;
    return a + ab * t;
}

}  // namespace

float BlobbyField::Plane::value(const Vec3& p, Vec3* gradient) const {
    // The point's raster position in the map (NDC scaled by its size) and
    // the stored depth there, bilinear between texel centres; where one of
    // the four texels is empty, the nearest texel's. Off the map, behind a
    // perspective map's eye or over an empty texel there is no surface to
    // be repelled from: 0.
    const DepthImage& img = *map;
    const auto& N = ndcFromObject.m;
    const float hx = N[0][0] * p.x + N[0][1] * p.y + N[0][2] * p.z + N[0][3];
    const float hy = N[1][0] * p.x + N[1][1] * p.y + N[1][2] * p.z + N[1][3];
    const float hw = N[3][0] * p.x + N[3][1] * p.y + N[3][2] * p.z + N[3][3];
    if (!(hw > 0)) return 0;
    const float W = float(img.width), H = float(img.height);
    const float nx = hx / hw, ny = hy / hw, x = nx * W, y = ny * H;
    if (!(x >= 0 && x < W && y >= 0 && y < H)) return 0;
    const float fx = x - 0.5f, fy = y - 0.5f;
    const int i0 = int(std::floor(fx)), j0 = int(std::floor(fy));
    const float tx = fx - float(i0), ty = fy - float(j0);
    const int ia = std::clamp(i0, 0, img.width - 1), ib = std::clamp(i0 + 1, 0, img.width - 1);
    const int ja = std::clamp(j0, 0, img.height - 1), jb = std::clamp(j0 + 1, 0, img.height - 1);
    const float z00 = img.at(ia, ja), z10 = img.at(ib, ja), z01 = img.at(ia, jb), z11 = img.at(ib, jb);
    float depth, dDepthDx = 0, dDepthDy = 0;
    if (std::isfinite(z00 + z10 + z01 + z11)) {
        depth = (z00 * (1 - tx) + z10 * tx) * (1 - ty) + (z01 * (1 - tx) + z11 * tx) * ty;
        if (ia != ib) dDepthDx = (z10 - z00) * (1 - ty) + (z11 - z01) * ty;
        if (ja != jb) dDepthDy = (z01 - z00) * (1 - tx) + (z11 - z10) * tx;
    } else {
        depth = img.at(std::min(int(x), img.width - 1), std::min(int(y), img.height - 1));
        if (!std::isfinite(depth)) return 0;
    }
    // Height above the stored surface along the map's view axis (its
    // camera-space z grows away from the eye).
    const auto& L = lightFromObject.m;
    const float height = depth - (L[2][0] * p.x + L[2][1] * p.y + L[2][2] * p.z + L[2][3]);
    float dz = 0;
    const float v = repulsion(height, cutoff, barrier, bulgeHeight, bulge, &dz);
    if (gradient && dz != 0) {
        // d(raster)/dp of the projective map, then the chain rule.
        const Vec3 dx = Vec3(N[0][0] - nx * N[3][0], N[0][1] - nx * N[3][1], N[0][2] - nx * N[3][2]) * (W / hw);
        const Vec3 dy = Vec3(N[1][0] - ny * N[3][0], N[1][1] - ny * N[3][1], N[1][2] - ny * N[3][2]) * (H / hw);
        *gradient = (dx * dDepthDx + dy * dDepthDy - Vec3(L[2][0], L[2][1], L[2][2])) * dz;
    }
    return v;
}

std::shared_ptr<const BlobbyField> BlobbyField::fromRecord(const scene::PrimitiveRecord& rec, Diagnostics& diag) {
    if (rec.intArgs.empty()) {
        diag.error(rec.loc, "Blobby: expected nleaf and a code array");
        return nullptr;
    }
    const int nleaf = rec.intArgs[0];
    const std::vector<int> code(rec.intArgs.begin() + 1, rec.intArgs.end());
    const std::vector<float>& floats = rec.floatArgs;
    auto field = std::make_shared<BlobbyField>();
    size_t pc = 0;
    auto operand = [&](const char* what, int* out) {
        if (pc >= code.size()) {
            diag.error(rec.loc, "Blobby: the code array ends inside instruction {}, expected {}", field->m_code.size(),
                       what);
            return false;
        }
        *out = code[pc++];
        return true;
    };
    auto floatsAt = [&](int index, int count, const char* what) -> const float* {
        if (index < 0 || size_t(index) + size_t(count) > floats.size()) {
            diag.error(rec.loc, "Blobby: instruction {} ({}) reads floats {}..{}, but the floats array has {}",
                       field->m_code.size(), what, index, index + count - 1, floats.size());
            return nullptr;
        }
        return floats.data() + index;
    };
    auto invert = [&](const float* f, Mat4* M, Mat4* inverse, const char* what) {
        *M = Mat4::fromRib(f);
        bool ok = false;
        *inverse = M->inverse(&ok);
        if (!ok || M->det3() == 0) {
            diag.error(rec.loc, "Blobby: instruction {} ({}) has a singular matrix", field->m_code.size(), what);
            return false;
        }
        return true;
    };
    const Bound3 unit(Vec3(-1), Vec3(1));
    std::map<std::string, std::shared_ptr<const DepthImage>> maps;  // by name; null: unreadable
    while (pc < code.size()) {
        const int opcode = code[pc++];
        Instruction ins;
        const int self = int(field->m_code.size());
        auto reference = [&](int* out) {
            if (!operand("an operand (the index of an earlier instruction)", out)) return false;
            if (*out < 0 || *out >= self) {
                diag.error(rec.loc, "Blobby: instruction {} refers to instruction {}, expected one of 0..{}", self,
                           *out, self - 1);
                return false;
            }
            ins.operands.push_back(*out);
            return true;
        };
        int idx = 0;
        switch (opcode) {
        case 1000: {
            if (!operand("the float index of a constant", &idx)) return nullptr;
            const float* f = floatsAt(idx, 1, "constant");
            if (!f) return nullptr;
            ins.op = Op::Constant;
            ins.constant = *f;
            ins.leaf = field->m_leaves++;
            break;
        }
        case 1001: {
            if (!operand("the float index of an ellipsoid's matrix", &idx)) return nullptr;
            const float* f = floatsAt(idx, 16, "ellipsoid");
            Mat4 M;
            if (!f || !invert(f, &M, &ins.leafFromObject, "ellipsoid")) return nullptr;
            ins.op = Op::Ellipsoid;
            ins.leaf = field->m_leaves++;
            ins.support = transformBound(M, unit);
            field->m_support.extend(ins.support);
            field->m_feature = std::min(field->m_feature, 0.5f * smallestScale(ins.leafFromObject));
            break;
        }
        case 1002: {
            if (!operand("the float index of a segment blob", &idx)) return nullptr;
            const float* f = floatsAt(idx, 23, "segment blob");
            Mat4 M;
            if (!f || !invert(f + 7, &M, &ins.leafFromObject, "segment blob")) return nullptr;
            const float radius = f[6];
            if (!(radius > 0)) {
                diag.error(rec.loc, "Blobby: instruction {} (segment blob) has radius {}, expected a positive radius",
                           self, radius);
                return nullptr;
            }
            ins.op = Op::Segment;
            ins.leaf = field->m_leaves++;
            // Measured in radii, the segment's field is a unit leaf's.
            ins.a = Vec3(f[0], f[1], f[2]) / radius;
            ins.b = Vec3(f[3], f[4], f[5]) / radius;
            ins.leafFromObject = Mat4::scale(Vec3(1 / radius)) * ins.leafFromObject;
            Bound3 b;
            b.extend(Vec3(f[0], f[1], f[2]));
            b.extend(Vec3(f[3], f[4], f[5]));
            b.min = b.min - Vec3(radius);
            b.max = b.max + Vec3(radius);
            ins.support = transformBound(M, b);
            field->m_support.extend(ins.support);
            field->m_feature = std::min(field->m_feature, 0.5f * smallestScale(ins.leafFromObject));
            break;
        }
        case 1003: {
            int stringIndex = 0;
            if (!operand("the string index of a depth-map plane", &stringIndex) ||
                !operand("the float index of a depth-map plane", &idx))
                return nullptr;
            const float* f = floatsAt(idx, 4, "depth-map plane");
            if (!f) return nullptr;
            if (stringIndex < 0 || size_t(stringIndex) >= rec.stringArgs.size()) {
                diag.error(rec.loc,
                           "Blobby: instruction {} (depth-map plane) reads string {}, but the strings array has {}",
                           self, stringIndex, rec.stringArgs.size());
                return nullptr;
            }
            if (!(f[0] > 0) || !(f[2] > 0) || !std::isfinite(f[0] + f[1] + f[2] + f[3])) {
                diag.error(rec.loc,
                           "Blobby: instruction {} (depth-map plane) has parameters {} {} {} {}, expected finite "
                           "ones with a positive cut-off height (the first) and bulge height (the third)",
                           self, f[0], f[1], f[2], f[3]);
                return nullptr;
            }
            ins.leaf = field->m_leaves++;
            const std::string& name = rec.stringArgs[size_t(stringIndex)];
            auto known = maps.find(name);
            if (known == maps.end()) {
                // Read once per Blobby (at most); what the reader says
                // becomes one warning at the request.
                Diagnostics reading;
                reading.setRecord(true);
                reading.setSink([](const Diagnostic&) {});
                known = maps.emplace(name, readPlaneMap(name, reading)).first;
                if (!known->second) {
                    std::string why;
                    for (const Diagnostic& d : reading.recorded()) why += (why.empty() ? "" : "; ") + d.message;
                    diag.warningOnce("blobby:plane:" + rec.loc.str() + ":" + name, rec.loc,
                                     "Blobby: cannot read the depth map of repelling plane leaf {} (opcode 1003): "
                                     "{}; the leaf contributes nothing to the field",
                                     ins.leaf, why);
                }
            }
            if (!known->second) {
                ins.op = Op::Skipped;
                break;
            }
            auto plane = std::make_shared<Plane>();
            plane->map = known->second;
            plane->ndcFromObject = plane->map->ndcFromWorld * rec.worldFromObject;
            plane->lightFromObject = plane->map->lightFromWorld * rec.worldFromObject;
            plane->cutoff = f[0];
            plane->barrier = f[1];
            plane->bulgeHeight = f[2];
            plane->bulge = f[3];
            ins.op = Op::Plane;
            ins.plane = std::move(plane);
            break;
        }
        case 0:
        case 1:
        case 2:
        case 3: {
            int count = 0;
            if (!operand("an operand count", &count)) return nullptr;
            if (count < 1) {
                diag.error(rec.loc, "Blobby: instruction {} has {} operands, expected at least 1", self, count);
                return nullptr;
            }
            for (int k = 0; k < count; ++k)
                if (!reference(&idx)) return nullptr;
            ins.op = opcode == 0 ? Op::Add : opcode == 1 ? Op::Multiply : opcode == 2 ? Op::Max : Op::Min;
            break;
        }
        case 4:
        case 5:
            if (!reference(&idx) || !reference(&idx)) return nullptr;
            ins.op = opcode == 4 ? Op::Subtract : Op::Divide;
            break;
        case 6:
        case 7:
            if (!reference(&idx)) return nullptr;
            ins.op = opcode == 6 ? Op::Negate : Op::Identity;
            break;
        default:
            diag.error(rec.loc,
                       "Blobby: unknown opcode {} at code position {}, expected 0-7 (operations) or 1000-1003 "
                       "(leaves)",
                       opcode, pc - 1);
            return nullptr;
        }
        field->m_code.push_back(std::move(ins));
    }
    if (field->m_leaves != nleaf) {
        diag.error(rec.loc, "Blobby: nleaf is {}, but the code has {} leaves (opcodes 1000-1003)", nleaf,
                   field->m_leaves);
        return nullptr;
    }
    // A plane has no support of its own (it stretches as far as its map):
    // it acts inside the other leaves' support box only, so the surface
    // stays bounded there whatever the plane's parameters.
    for (Instruction& ins : field->m_code)
        if (ins.op == Op::Plane) ins.support = field->m_support;
    if (!field->m_support.empty()) {
        const Vec3 lo = field->m_support.min, hi = field->m_support.max;
        const bool finite = std::isfinite(lo.x) && std::isfinite(lo.y) && std::isfinite(lo.z) &&
                            std::isfinite(hi.x) && std::isfinite(hi.y) && std::isfinite(hi.z) &&
                            std::isfinite(field->m_feature) && field->m_feature > 0;
        if (!finite) {
            diag.error(rec.loc, "Blobby: a leaf's matrix or radius gives a non-finite or zero-sized leaf, expected "
                                "finite, invertible leaves");
            return nullptr;
        }
    }
    field->buildBlocks();
    return field;
}

std::vector<BlobbyField::Instruction> BlobbyField::reduce(const std::vector<Instruction>& code,
                                                          const Bound3& region) {
    // zero[k]: instruction k is 0 throughout the region; map[k]: its index
    // in the reduced code.
    std::vector<char> zero(code.size(), 0);
    std::vector<int> map(code.size(), -1);
    std::vector<Instruction> out;
    int zeroConstant = -1;
    auto ref = [&](int o) {
        if (!zero[size_t(o)]) return map[size_t(o)];
        if (zeroConstant < 0) {
            Instruction c;
            c.op = Op::Constant;
            zeroConstant = int(out.size());
            out.push_back(c);
        }
        return zeroConstant;
    };
    for (size_t k = 0; k < code.size(); ++k) {
        const Instruction& ins = code[k];
        Instruction r = ins;
        r.operands.clear();
        bool isZero = false;
        auto z = [&](int i) { return zero[size_t(ins.operands[size_t(i)])] != 0; };
        switch (ins.op) {
        case Op::Constant: isZero = ins.constant == 0; break;
        case Op::Ellipsoid:
        case Op::Segment:
        case Op::Plane: {
            const Bound3& b = ins.support;
            isZero = b.max.x < region.min.x || b.max.y < region.min.y || b.max.z < region.min.z ||
                     b.min.x > region.max.x || b.min.y > region.max.y || b.min.z > region.max.z;
            break;
        }
        case Op::Skipped: isZero = true; break;
        case Op::Add:
            for (int o : ins.operands)
                if (!zero[size_t(o)]) r.operands.push_back(map[size_t(o)]);
            isZero = r.operands.empty();
            break;
        case Op::Multiply:
            for (int o : ins.operands) {
                isZero |= zero[size_t(o)] != 0;
                r.operands.push_back(map[size_t(o)]);
            }
            break;
        case Op::Max:
        case Op::Min:
            isZero = true;
            for (int o : ins.operands) isZero &= zero[size_t(o)] != 0;
            if (!isZero) {
                // One 0 stands for all of them: max(0, 0, x) = max(0, x).
                bool zeroAdded = false;
                for (int o : ins.operands) {
                    if (zero[size_t(o)] && zeroAdded) continue;
                    zeroAdded |= zero[size_t(o)] != 0;
                    r.operands.push_back(ref(o));
                }
            }
            break;
        case Op::Subtract:
            isZero = z(0) && z(1);
            if (!isZero) {
                if (z(1)) {
                    r.op = Op::Identity;
                    r.operands = {map[size_t(ins.operands[0])]};
                } else if (z(0)) {
                    r.op = Op::Negate;
                    r.operands = {map[size_t(ins.operands[1])]};
                } else {
                    r.operands = {map[size_t(ins.operands[0])], map[size_t(ins.operands[1])]};
                }
            }
            break;
        case Op::Divide:
            // 0 / d is 0, and so is n / 0 (Aqsis's rule).
            isZero = z(0) || z(1);
            if (!isZero) r.operands = {map[size_t(ins.operands[0])], map[size_t(ins.operands[1])]};
            break;
        case Op::Negate:
        case Op::Identity:
            isZero = z(0);
            if (!isZero) r.operands = {map[size_t(ins.operands[0])]};
            break;
        }
        zero[k] = isZero;
        if (!isZero) {
            map[k] = int(out.size());
            out.push_back(std::move(r));
        }
    }
    // The field is the last instruction; when it is 0 here, so is the code.
    if (code.empty() || zero.back()) return {};
    if (map.back() != int(out.size()) - 1) {
        Instruction last;
        last.op = Op::Identity;
        last.operands = {map.back()};
        out.push_back(last);
    }
    return out;
}

void BlobbyField::buildBlocks() {
    m_outside = reduce(m_code, Bound3(Vec3(kInfinity), Vec3(kInfinity)));
    if (m_support.empty()) return;
    // About two leaves per block, at most 16 blocks along an axis.
    const int n = std::clamp(int(std::ceil(std::cbrt(2.0 * m_leaves))), 1, 16);
    const Vec3 ext = m_support.diagonal();
    for (int a = 0; a < 3; ++a) m_blockCount[a] = ext[a] > 0 ? n : 1;
    m_blockSize = Vec3(ext.x / float(m_blockCount[0]), ext.y / float(m_blockCount[1]), ext.z / float(m_blockCount[2]));
    m_blocks.resize(size_t(m_blockCount[0]) * size_t(m_blockCount[1]) * size_t(m_blockCount[2]));
    // Code that folds badly (e.g. many constants) could take much memory
    // in every block: past 64 MB of folded code in all, points run the
    // whole code instead.
    size_t k = 0, bytes = 0;
    constexpr size_t kMaxBytes = size_t(64) << 20;
    for (int z = 0; z < m_blockCount[2]; ++z)
        for (int y = 0; y < m_blockCount[1]; ++y)
            for (int x = 0; x < m_blockCount[0]; ++x) {
                const Vec3 lo = m_support.min + Vec3(float(x), float(y), float(z)) * m_blockSize;
                // Blocks overlap by a sliver so rounding in locating a point
                // can never pick a block whose reduced code misses a leaf.
                const Vec3 pad = m_blockSize * 1e-3f;
                m_blocks[k] = reduce(m_code, Bound3(lo - pad, lo + m_blockSize + pad));
                for (const Instruction& ins : m_blocks[k]) bytes += sizeof(Instruction) + 4 * ins.operands.size();
                ++k;
                if (bytes > kMaxBytes) {
                    m_blocks.clear();
                    return;
                }
            }
}

float BlobbyField::value(const Vec3& p, float* leafValues) const { return evaluate(p, leafValues, nullptr); }

Vec3 BlobbyField::gradient(const Vec3& p) const {
    Vec3 g;
    evaluate(p, nullptr, &g);
    return g;
}

float BlobbyField::evaluate(const Vec3& p, float* leafValues, Vec3* gradient) const {
    // Each instruction's value, and with `gradient` its gradient, by the
    // rules of differentiation for each operation.
    const std::vector<Instruction>* program = m_blocks.empty() ? &m_code : &m_outside;
    if (!m_blocks.empty()) {
        int c[3];
        bool in = true;
        for (int a = 0; a < 3; ++a) {
            const float t = (p[a] - m_support.min[a]) / m_blockSize[a];
            in &= t >= 0 && t <= float(m_blockCount[a]);
            c[a] = std::clamp(int(in ? t : 0), 0, m_blockCount[a] - 1);
        }
        if (in) program = &m_blocks[(size_t(c[2]) * size_t(m_blockCount[1]) + size_t(c[1])) * size_t(m_blockCount[0]) +
                                    size_t(c[0])];
    }
    const std::vector<Instruction>& code = *program;
    if (leafValues) std::fill(leafValues, leafValues + m_leaves, 0.0f);
    thread_local std::vector<float> r;
    thread_local std::vector<Vec3> dr;
    r.resize(code.size());
    if (gradient) dr.resize(code.size());
    const bool grad = gradient != nullptr;
    for (size_t k = 0; k < code.size(); ++k) {
        const Instruction& ins = code[k];
        float v = 0;
        Vec3 g(0);
        // A leaf at unit-space offset d (from its centre, or from the
        // nearest point of its segment): field (1 - |d|^2)^3, gradient
        // -6 (1 - |d|^2)^2 L^T d in object space, L = leafFromObject.
        // Outside its support box a leaf is exactly 0: skip its transform.
        auto outside = [&] {
            const Bound3& b = ins.support;
            return p.x < b.min.x || p.y < b.min.y || p.z < b.min.z || p.x > b.max.x || p.y > b.max.y || p.z > b.max.z;
        };
        auto leaf = [&](const Vec3& d) {
            const float r2 = dot(d, d);
            if (r2 >= 1) return;
            const float s = 1 - r2;
            v = s * s * s;
            if (grad) {
                const Mat4& L = ins.leafFromObject;
                const Vec3 lt(L.m[0][0] * d.x + L.m[1][0] * d.y + L.m[2][0] * d.z,
                              L.m[0][1] * d.x + L.m[1][1] * d.y + L.m[2][1] * d.z,
                              L.m[0][2] * d.x + L.m[1][2] * d.y + L.m[2][2] * d.z);
                g = lt * (-6 * s * s);
            }
        };
        switch (ins.op) {
        case Op::Constant: v = ins.constant; break;
        case Op::Ellipsoid: {
            if (outside()) break;
            const Vec3 q = ins.leafFromObject.point(p);
            leaf(q);
            break;
        }
        case Op::Segment: {
            if (outside()) break;
            const Vec3 q = ins.leafFromObject.point(p);
            leaf(q - nearestOnSegment(q, ins.a, ins.b));
            break;
        }
        case Op::Plane:
            if (outside()) break;
            v = ins.plane->value(p, grad ? &g : nullptr);
            break;
        case Op::Skipped: break;
        case Op::Add:
            for (int o : ins.operands) {
                v += r[size_t(o)];
                if (grad) g = g + dr[size_t(o)];
            }
            break;
        case Op::Multiply:
            v = 1;
            for (int o : ins.operands) {
                if (grad) g = g * r[size_t(o)] + dr[size_t(o)] * v;
                v *= r[size_t(o)];
            }
            break;
        case Op::Max:
        case Op::Min: {
            int best = ins.operands[0];
            for (int o : ins.operands)
                if (ins.op == Op::Max ? r[size_t(o)] > r[size_t(best)] : r[size_t(o)] < r[size_t(best)]) best = o;
            v = r[size_t(best)];
            if (grad) g = dr[size_t(best)];
            break;
        }
        case Op::Subtract:
            v = r[size_t(ins.operands[0])] - r[size_t(ins.operands[1])];
            if (grad) g = dr[size_t(ins.operands[0])] - dr[size_t(ins.operands[1])];
            break;
        case Op::Divide: {
            // A zero divisor gives 0, as in Aqsis, rather than an infinity.
            const float n = r[size_t(ins.operands[0])], d = r[size_t(ins.operands[1])];
            if (d != 0) {
                v = n / d;
                if (grad) g = (dr[size_t(ins.operands[0])] * d - dr[size_t(ins.operands[1])] * n) / (d * d);
            }
            break;
        }
        case Op::Negate:
            v = -r[size_t(ins.operands[0])];
            if (grad) g = -dr[size_t(ins.operands[0])];
            break;
        case Op::Identity:
            v = r[size_t(ins.operands[0])];
            if (grad) g = dr[size_t(ins.operands[0])];
            break;
        }
        r[k] = v;
        if (grad) dr[k] = g;
        if (leafValues && ins.leaf >= 0) leafValues[ins.leaf] = v;
    }
    if (r.empty()) {
        if (gradient) *gradient = Vec3(0);
        return 0;
    }
    if (gradient) *gradient = dr.back();
    return r.back();
}

Vec3 BlobbyField::project(const Vec3& start, float maxStep, Vec3* outward) const {
    Vec3 p = start, g;
    float f = evaluate(p, nullptr, &g);
    for (int it = 0; it < 12; ++it) {
        // Converged to float precision of the field (about 1e-7 of its
        // unit peak), or stuck where the field is flat (outside every
        // leaf, or at a leaf's rim where its slope vanishes): a tiny
        // gradient would make an infinite step.
        const float gl = length(g);
        if (!(gl > 1e-12f && gl < 1e30f) || std::abs(kBlobbyThreshold - f) < 1e-6f) break;
        const float dist = std::clamp((kBlobbyThreshold - f) / gl, -maxStep, maxStep);
        const Vec3 next = p + g * (dist / gl);
        Vec3 gNew;
        const float fNew = evaluate(next, nullptr, &gNew);
        if (!std::isfinite(fNew)) break;
        if ((fNew - kBlobbyThreshold) * (f - kBlobbyThreshold) < 0 &&
            std::abs(fNew - kBlobbyThreshold) > std::abs(f - kBlobbyThreshold)) {
            // The step crossed the surface and landed farther from it than
            // it started: Newton overshooting where the field is strongly
            // curved (a repelling plane's -B/z), possibly into a region
            // with no slope to come back along (under a plane's surface).
            // The step brackets the surface: bisect it there.
            Vec3 a = p, b = next;
            float fa = f, fb = fNew;
            for (int k = 0; k < 40 && std::abs(fb - kBlobbyThreshold) >= 1e-6f; ++k) {
                const Vec3 m = (a + b) * 0.5f;
                if (m == a || m == b) break;  // no float between them
                const float fm = evaluate(m, nullptr, nullptr);
                if ((fm - kBlobbyThreshold) * (fa - kBlobbyThreshold) > 0) {
                    a = m;
                    fa = fm;
                } else {
                    b = m;
                    fb = fm;
                }
                if (std::abs(fa - kBlobbyThreshold) < std::abs(fb - kBlobbyThreshold)) {
                    std::swap(a, b);  // b: the nearer the threshold
                    std::swap(fa, fb);
                }
            }
            p = b;
            f = evaluate(p, nullptr, &gNew);
            if (length(gNew) > 1e-12f && length(gNew) < 1e30f) g = gNew;
            break;
        }
        p = next;
        f = fNew;
        if (length(gNew) > 1e-12f && length(gNew) < 1e30f) g = gNew;
    }
    const float gl = length(g);
    if (outward) *outward = gl > 1e-12f && gl < 1e30f ? g * (-1 / gl) : Vec3(0, 0, 1);
    return p;
}

namespace {

/// How far the surface over each triangle stands off it, from its centre and
/// edge midpoints; doubled (and a little more) for the bound.
void padTriangles(BlobbyMeshData& mesh) {
    const float h = mesh.maxStep;
    mesh.pad.resize(mesh.triangles.size());
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        const auto& [a, b, c] = mesh.triangles[t];
        float d = 0;
        for (const Vec3& x : {(a + b + c) / 3, (a + b) * 0.5f, (b + c) * 0.5f, (a + c) * 0.5f})
            d = std::max(d, length(mesh.field->project(x, h, nullptr) - x));
        mesh.pad[t] = 2 * d + 0.05f * h;
    }
}

}  // namespace

std::shared_ptr<BlobbyMeshData> polygonizeBlobby(const scene::PrimitiveRecord& rec,
                                                 std::shared_ptr<const BlobbyField> field, int maxCells,
                                                 Diagnostics& diag) {
    auto mesh = std::make_shared<BlobbyMeshData>();
    mesh->field = field;
    const Bound3 support = field->support();
    if (support.empty() || !(field->featureSize() < kInfinity)) return mesh;
    // A third of the smallest surface radius: a lone leaf spans six cells,
    // enough for the coarse triangles to find every leaf and the bridges
    // between them; the pieces' projection supplies the detail.
    float h = field->featureSize() / 3;
    const Vec3 ext = support.diagonal();
    const float longest = std::max({ext.x, ext.y, ext.z});
    // Cost is a visit of every leaf per lattice vertex (most end at the
    // leaf's support box): cap both the cells along an axis and the visits
    // (2e8, about a second).
    const double budget = 2e8 / std::max(field->leafCount(), 1);
    float hMin = longest / float(std::max(maxCells - 2, 1));
    const double cellsAtMin = double(ext.x / hMin + 3) * double(ext.y / hMin + 3) * double(ext.z / hMin + 3);
    if (cellsAtMin > budget) hMin *= float(std::cbrt(cellsAtMin / budget));
    if (h < hMin) {
        diag.warning(rec.loc,
                     "Blobby: its smallest leaf asks for a {:.3g}-unit polygonisation lattice; capped at {:.3g} "
                     "(at most {} cells along an axis and 2e8 leaf visits): leaves or gaps smaller than "
                     "that may be lost",
                     h, hMin, maxCells);
        h = hMin;
    }
    mesh->maxStep = h;
    const Vec3 origin = support.min - Vec3(h);
    const int nx = int(std::ceil(ext.x / h)) + 2, ny = int(std::ceil(ext.y / h)) + 2, nz = int(std::ceil(ext.z / h)) + 2;
    auto vid = [&](int i, int j, int k) { return (int64_t(k) * (ny + 1) + j) * (nx + 1) + i; };
    auto pos = [&](int64_t id) {
        const int64_t i = id % (nx + 1), j = (id / (nx + 1)) % (ny + 1), k = id / ((nx + 1) * int64_t(ny + 1));
        return origin + Vec3(float(i), float(j), float(k)) * h;
    };
    std::vector<float> values(size_t(nx + 1) * size_t(ny + 1) * size_t(nz + 1));
    for (int k = 0; k <= nz; ++k)
        for (int j = 0; j <= ny; ++j)
            for (int i = 0; i <= nx; ++i) values[size_t(vid(i, j, k))] = field->value(pos(vid(i, j, k)));

    // Each edge's crossing, projected onto the surface once, so the
    // triangles on either side of an edge share the same corner exactly.
    std::unordered_map<uint64_t, Vec3> corners;
    auto crossing = [&](int64_t p, int64_t q) {
        if (p > q) std::swap(p, q);
        const uint64_t key = uint64_t(p) * uint64_t((nx + 1) * int64_t(ny + 1) * (nz + 1)) + uint64_t(q);
        auto it = corners.find(key);
        if (it != corners.end()) return it->second;
        const float fp = values[size_t(p)], fq = values[size_t(q)];
        const float t = std::clamp((kBlobbyThreshold - fp) / (fq - fp), 0.0f, 1.0f);
        const Vec3 x = field->project(pos(p) + (pos(q) - pos(p)) * t, h, nullptr);
        corners.emplace(key, x);
        return x;
    };
    auto emit = [&](Vec3 a, Vec3 b, Vec3 c) {
        const Vec3 n = cross(b - a, c - a);
        if (!(dot(n, n) > 1e-14f * h * h * h * h)) return;
        Vec3 outward;
        field->project((a + b + c) / 3, h, &outward);
        if (dot(n, outward) < 0) std::swap(b, c);
        mesh->triangles.push_back({a, b, c});
    };
    // Kuhn's six tetrahedra of a cube, each a path from corner 0 to corner
    // 7 along the axes in one order: neighbouring cubes cut their shared
    // faces along the same diagonal, so the triangles meet edge to edge.
    static const int kAxisOrders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                for (const auto& order : kAxisOrders) {
                    int64_t v[4];
                    int c[3] = {i, j, k};
                    v[0] = vid(c[0], c[1], c[2]);
                    for (int s = 0; s < 3; ++s) {
                        ++c[order[s]];
                        v[s + 1] = vid(c[0], c[1], c[2]);
                    }
                    int in[4], out[4], nin = 0, nout = 0;
                    for (int s = 0; s < 4; ++s)
                        (values[size_t(v[s])] >= kBlobbyThreshold ? in[nin++] : out[nout++]) = s;
                    if (nin == 0 || nout == 0) continue;
                    if (nin == 1 || nout == 1) {
                        const int lone = nin == 1 ? in[0] : out[0];
                        const int* others = nin == 1 ? out : in;
                        emit(crossing(v[lone], v[others[0]]), crossing(v[lone], v[others[1]]),
                             crossing(v[lone], v[others[2]]));
                    } else {
                        const Vec3 ik = crossing(v[in[0]], v[out[0]]), il = crossing(v[in[0]], v[out[1]]),
                                   jl = crossing(v[in[1]], v[out[1]]), jk = crossing(v[in[1]], v[out[0]]);
                        emit(ik, il, jl);
                        emit(ik, jl, jk);
                    }
                }

    padTriangles(*mesh);
    return mesh;
}

BlobbyMesh::BlobbyMesh(std::shared_ptr<const scene::PrimitiveRecord> record,
                       std::shared_ptr<const BlobbyMeshData> data, int first, int end)
    : Primitive(std::move(record)), m_data(std::move(data)), m_first(first), m_end(end) {
    for (int t = m_first; t < m_end; ++t) {
        const Vec3 pad(m_data->pad[size_t(t)]);
        for (const Vec3& p : m_data->triangles[size_t(t)]) {
            m_bound.extend(p - pad);
            m_bound.extend(p + pad);
        }
    }
}

void BlobbyMesh::split(bool, std::vector<PrimitivePtr>& out) const {
    if (m_end - m_first == 1) {
        out.push_back(std::make_unique<BlobbyPiece>(recordPtr(), m_data, m_first, ParamRange{}));
        return;
    }
    const int mid = m_first + (m_end - m_first) / 2;
    out.push_back(std::make_unique<BlobbyMesh>(recordPtr(), m_data, m_first, mid));
    out.push_back(std::make_unique<BlobbyMesh>(recordPtr(), m_data, mid, m_end));
}

Grid BlobbyMesh::dice(int, int) const {
    UMBRA_CHECK(false, "BlobbyMesh::dice called on a Blobby that must be split first");
    return {};
}

BlobbyPiece::BlobbyPiece(std::shared_ptr<const scene::PrimitiveRecord> record,
                         std::shared_ptr<const BlobbyMeshData> data, int triangle, const ParamRange& range)
    : Primitive(std::move(record)), m_data(std::move(data)), m_triangle(triangle), m_range(range) {}

Vec3 BlobbyPiece::flatPoint(float u, float v) const {
    const auto& [a, b, c] = m_data->triangles[size_t(m_triangle)];
    return (a + (b - a) * u) * (1 - v) + c * v;
}

Bound3 BlobbyPiece::bound() const {
    // A bilinear patch lies in the hull of its four corners.
    Bound3 b;
    for (float u : {m_range.u0, m_range.u1})
        for (float v : {m_range.v0, m_range.v1}) b.extend(flatPoint(u, v));
    const Vec3 pad(m_data->pad[size_t(m_triangle)]);
    return Bound3(b.min - pad, b.max + pad);
}

void BlobbyPiece::split(bool splitU, std::vector<PrimitivePtr>& out) const {
    // Projection is discontinuous where a coarse triangle spans a gap the
    // lattice missed (points on either side go to different sheets): no
    // split makes such a piece small on screen. Past 2^-16 of the
    // triangle's parameter area it is dropped (a pinhole at most) rather
    // than split without end.
    if ((m_range.u1 - m_range.u0) * (m_range.v1 - m_range.v0) < kMinPieceArea) return;
    for (int k = 0; k < 2; ++k)
        out.push_back(std::make_unique<BlobbyPiece>(recordPtr(), m_data, m_triangle, m_range.half(splitU, k == 1)));
}

void BlobbyPiece::dicePositions(int nu, int nv, std::vector<Vec3>& P) const {
    thread_local std::vector<float> a, b;
    m_range.steps(nu, nv, a, b);
    P.resize(size_t(nu + 1) * size_t(nv + 1));
    size_t k = 0;
    for (float v : b)
        for (float u : a) P[k++] = m_data->field->project(flatPoint(u, v), m_data->maxStep, nullptr);
}

Grid BlobbyPiece::dice(int nu, int nv) const {
    Grid g;
    std::vector<float> a, b;
    initGrid(g, nu, nv, m_range, ParamMap{}, a, b);
    g.N.resize(g.P.size());
    g.ownNormals = true;
    const BlobbyField& field = *m_data->field;
    const SurfaceData& sd = *m_data->vars;
    const size_t leaves = size_t(field.leafCount()), n = g.P.size();
    // Per vertex, each leaf's share of the field there: vertex and varying
    // values are blended by it (RI spec 3.2 §5.6).
    std::vector<float> share(n * leaves);
    size_t k = 0;
    for (float v : b)
        for (float u : a) {
            g.P[k] = field.project(flatPoint(u, v), m_data->maxStep, &g.N[k]);
            float* w = share.data() + k * leaves;
            field.value(g.P[k], w);
            float sum = 0;
            for (size_t l = 0; l < leaves; ++l) sum += (w[l] = std::max(w[l], 0.0f));
            for (size_t l = 0; l < leaves; ++l) w[l] = sum > 0 ? w[l] / sum : 1.0f / float(leaves);
            ++k;
        }
    for (const PrimVar& var : sd.vars) {
        if (var.isNormal) continue;  // the field's gradient is the normal
        const bool perLeaf = var.storage != ri::StorageClass::Constant && var.storage != ri::StorageClass::Uniform;
        GridVar& gv = addGridVar(g, var, perLeaf);
        if (!perLeaf) {
            std::copy(var.at(0), var.at(0) + var.components, gv.data.begin());
            continue;
        }
        for (size_t p = 0; p < n; ++p) {
            float* o = gv.data.data() + p * size_t(var.components);
            std::fill(o, o + var.components, 0.0f);
            for (size_t l = 0; l < leaves; ++l) {
                const float w = share[p * leaves + l];
                if (w == 0) continue;
                const float* x = var.at(l);
                for (int c = 0; c < var.components; ++c) o[c] += w * x[c];
            }
        }
    }
    addDefaultVars(sd, g);
    return g;
}

namespace {

/// A Blobby record's field, its primitive variables and its coarse
/// triangles; null when it is malformed (reported through `diag`).
std::shared_ptr<BlobbyMeshData> blobbyMesh(const scene::PrimitiveRecord& record, Diagnostics& diag) {
    auto field = BlobbyField::fromRecord(record, diag);
    if (!field) return nullptr;
    ClassCounts counts;
    counts.uniform = 1;
    counts.uniformWhat = "one for the Blobby";
    counts.varying = counts.vertex = counts.faceVarying = size_t(field->leafCount());
    counts.varyingWhat = counts.vertexWhat = counts.faceVaryingWhat = "one per leaf";
    auto vars = readSurfaceData(record, counts, false, diag);
    if (!vars) return nullptr;
    constexpr int kMaxCellsPerAxis = 96;
    auto mesh = polygonizeBlobby(record, field, kMaxCellsPerAxis, diag);
    mesh->vars = std::move(vars);
    return mesh;
}

}  // namespace

void makeBlobby(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                std::vector<PrimitivePtr>& out) {
    auto mesh = blobbyMesh(*record, diag);
    if (!mesh || mesh->triangles.empty()) return;
    const int n = int(mesh->triangles.size());
    out.push_back(std::make_unique<BlobbyMesh>(std::move(record), std::move(mesh), 0, n));
}

std::shared_ptr<BlobbyMeshData> carryBlobbyMesh(const BlobbyMeshData& from, std::shared_ptr<const BlobbyField> to,
                                                std::string* why) {
    using Op = BlobbyField::Op;
    const BlobbyField& source = *from.field;
    const int leaves = source.leafCount();
    if (to->leafCount() != leaves) {
        *why = fmt::format("it has {} leaves where the first shape has {}", to->leafCount(), leaves);
        return nullptr;
    }
    // Each leaf's instruction in both shapes, and the first shape's leaf
    // space mapped into the other's object space.
    std::vector<const BlobbyField::Instruction*> before(static_cast<size_t>(leaves)), after(static_cast<size_t>(leaves));
    for (const auto& ins : source.code())
        if (ins.leaf >= 0) before[size_t(ins.leaf)] = &ins;
    for (const auto& ins : to->code())
        if (ins.leaf >= 0) after[size_t(ins.leaf)] = &ins;
    std::vector<Mat4> objectFromLeaf(static_cast<size_t>(leaves));
    for (int l = 0; l < leaves; ++l) {
        if (before[size_t(l)]->op != after[size_t(l)]->op) {
            *why = fmt::format("its leaf {} is of another kind than the first shape's", l);
            return nullptr;
        }
        objectFromLeaf[size_t(l)] = after[size_t(l)]->leafFromObject.inverse();
    }
    auto mesh = std::make_shared<BlobbyMeshData>();
    mesh->field = to;
    mesh->vars = from.vars;
    mesh->maxStep = from.maxStep;
    std::vector<float> share(static_cast<size_t>(leaves));
    // A corner's place on the other shape: where each leaf it belongs to
    // takes it (the same point of the leaf's own space; along a segment,
    // the same distance from the same point of it), blended by the leaves'
    // fields, then projected onto the surface. A lone leaf's corners land
    // on its surface exactly: the projection only settles rounding.
    auto carry = [&](const Vec3& p) {
        source.value(p, share.data());
        Vec3 sum(0.0f);
        float weights = 0;
        for (int l = 0; l < leaves; ++l) {
            const BlobbyField::Instruction& a = *before[size_t(l)];
            const float w = share[size_t(l)];
            if (!(w > 0) || (a.op != Op::Ellipsoid && a.op != Op::Segment)) continue;
            Vec3 q = a.leafFromObject.point(p);
            if (a.op == Op::Segment) {
                const BlobbyField::Instruction& b = *after[size_t(l)];
                const Vec3 axis = a.b - a.a;
                const float len2 = dot(axis, axis);
                const float t = len2 > 0 ? std::clamp(dot(q - a.a, axis) / len2, 0.0f, 1.0f) : 0.0f;
                q = q - (a.a + axis * t) + (b.a + (b.b - b.a) * t);
            }
            sum = sum + objectFromLeaf[size_t(l)].point(q) * w;
            weights += w;
        }
        const Vec3 guess = weights > 0 ? sum / weights : p;
        return to->project(guess, from.maxStep, nullptr);
    };
    // Neighbouring triangles share their corners exactly (polygonizeBlobby):
    // each is carried once, so they still meet.
    struct CornerHash {
        size_t operator()(const Vec3& p) const {
            return std::hash<float>()(p.x) ^ (std::hash<float>()(p.y) * 31) ^ (std::hash<float>()(p.z) * 961);
        }
    };
    struct SameCorner {
        bool operator()(const Vec3& a, const Vec3& b) const { return a.x == b.x && a.y == b.y && a.z == b.z; }
    };
    std::unordered_map<Vec3, Vec3, CornerHash, SameCorner> carried;
    auto carryOnce = [&](const Vec3& p) {
        auto it = carried.find(p);
        if (it == carried.end()) it = carried.emplace(p, carry(p)).first;
        return it->second;
    };
    mesh->triangles.reserve(from.triangles.size());
    for (const auto& [a, b, c] : from.triangles) mesh->triangles.push_back({carryOnce(a), carryOnce(b), carryOnce(c)});
    padTriangles(*mesh);
    return mesh;
}

void makeDeformingBlobby(std::shared_ptr<const scene::PrimitiveRecord> record, Diagnostics& diag,
                         std::vector<PrimitivePtr>& out) {
    auto first = blobbyMesh(*record, diag);
    if (!first || first->triangles.empty()) return;
    const int n = int(first->triangles.size());
    std::vector<PrimitivePtr> shapes;
    shapes.push_back(std::make_unique<BlobbyMesh>(record, first, 0, n));
    for (const scene::PrimitiveRecord& shape : record->shapes) {
        auto field = BlobbyField::fromRecord(shape, diag);
        std::string why;
        auto carried = field ? carryBlobbyMesh(*first, field, &why) : nullptr;
        if (!carried) {
            if (field) diag.error(shape.loc, "Blobby: this motion shape cannot blur with the first: {} (the Blobby "
                                  "renders unblurred)", why);
            out.push_back(std::move(shapes[0]));
            return;
        }
        shapes.push_back(std::make_unique<BlobbyMesh>(std::make_shared<const scene::PrimitiveRecord>(shape),
                                                      std::move(carried), 0, n));
    }
    out.push_back(std::make_unique<DeformingPrimitive>(std::move(shapes)));
}

}  // namespace umbra::geometry
