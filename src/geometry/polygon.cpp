#include "umbra/geometry/polygon.h"

#include <algorithm>
#include <cmath>

namespace umbra::geometry {

namespace {

// Newell's normal: robust for non-planar and concave loops.
Vec3 newellNormal(const Vec3* p, int n) {
    Vec3 N(0.0f);
    for (int i = 0; i < n; ++i) {
        const Vec3& a = p[i];
        const Vec3& b = p[(i + 1) % n];
        N.x += (a.y - b.y) * (a.z + b.z);
        N.y += (a.z - b.z) * (a.x + b.x);
        N.z += (a.x - b.x) * (a.y + b.y);
    }
    return N;
}

// Projects onto the coordinate plane most nearly parallel to the polygon,
// ordered so that a loop winding counter-clockwise about `normal` is
// counter-clockwise in 2-D.
struct Projector {
    int ax0 = 0, ax1 = 1;
    explicit Projector(const Vec3& normal) {
        const Vec3 a(std::abs(normal.x), std::abs(normal.y), std::abs(normal.z));
        int drop = (a.x >= a.y && a.x >= a.z) ? 0 : (a.y >= a.z ? 1 : 2);
        ax0 = (drop + 1) % 3;
        ax1 = (drop + 2) % 3;
        if (normal[drop] < 0) std::swap(ax0, ax1);
    }
    Vec2 operator()(const Vec3& p) const { return {p[ax0], p[ax1]}; }
};

inline double cross2(const Vec2& o, const Vec2& a, const Vec2& b) {
    return double(a.x - o.x) * double(b.y - o.y) - double(a.y - o.y) * double(b.x - o.x);
}

double signedArea(const std::vector<Vec2>& p, const std::vector<int>& loop) {
    double s = 0;
    for (size_t i = 0; i < loop.size(); ++i) {
        const Vec2& a = p[size_t(loop[i])];
        const Vec2& b = p[size_t(loop[(i + 1) % loop.size()])];
        s += double(a.x) * b.y - double(b.x) * a.y;
    }
    return 0.5 * s;
}

// Closed triangle test (points on an edge count as inside).
bool inTriangle(const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
    return cross2(a, b, p) >= 0 && cross2(b, c, p) >= 0 && cross2(c, a, p) >= 0;
}

bool samePoint(const Vec2& a, const Vec2& b) { return a.x == b.x && a.y == b.y; }

// Splices `hole` (clockwise) into `poly` (counter-clockwise) through a
// bridge from the hole's rightmost vertex M to a vertex of `poly` visible
// from it (Eberly, "Triangulation by Ear Clipping", §3).
void bridgeHole(const std::vector<Vec2>& p, std::vector<int>& poly, const std::vector<int>& hole) {
    size_t mi = 0;
    for (size_t i = 1; i < hole.size(); ++i)
        if (p[size_t(hole[i])].x > p[size_t(hole[mi])].x) mi = i;
    const Vec2 M = p[size_t(hole[mi])];
    // Nearest crossing of the ray M + t (1, 0) with an edge of the outline.
    double bestX = kInfinity;
    size_t bestVertex = 0;
    bool found = false;
    Vec2 I;
    for (size_t i = 0; i < poly.size(); ++i) {
        const Vec2& a = p[size_t(poly[i])];
        const Vec2& b = p[size_t(poly[(i + 1) % poly.size()])];
        if ((a.y > M.y) == (b.y > M.y) && a.y != M.y && b.y != M.y) continue;
        if (a.y == b.y) {
            if (a.y != M.y) continue;
            const float x = std::min(a.x, b.x);
            if (x >= M.x && x < bestX) {
                bestX = x;
                bestVertex = a.x < b.x ? i : (i + 1) % poly.size();
                found = true;
                I = {x, M.y};
            }
            continue;
        }
        const double t = (double(M.y) - a.y) / (double(b.y) - a.y);
        if (t < 0 || t > 1) continue;
        const double x = a.x + t * (double(b.x) - a.x);
        if (x < M.x || x >= bestX) continue;
        bestX = x;
        I = {float(x), M.y};
        found = true;
        bestVertex = a.x > b.x ? i : (i + 1) % poly.size();
        if (t == 0) bestVertex = i;
        if (t == 1) bestVertex = (i + 1) % poly.size();
    }
    if (!found) {
        // Hole outside the outline: connect to the nearest vertex anyway.
        double best = kInfinity;
        for (size_t i = 0; i < poly.size(); ++i) {
            const Vec2 d = p[size_t(poly[i])] - M;
            const double dd = double(d.x) * d.x + double(d.y) * d.y;
            if (dd < best) { best = dd; bestVertex = i; }
        }
    } else {
        const Vec2 P = p[size_t(poly[bestVertex])];
        if (!samePoint(P, I)) {
            // A reflex outline vertex inside triangle (M, I, P) would block the
            // bridge; the one making the smallest angle with the ray is visible.
            double bestAngle = kInfinity, bestDist = kInfinity;
            const bool ccw = cross2(M, I, P) >= 0;
            for (size_t i = 0; i < poly.size(); ++i) {
                const Vec2& r = p[size_t(poly[i])];
                const Vec2& prev = p[size_t(poly[(i + poly.size() - 1) % poly.size()])];
                const Vec2& next = p[size_t(poly[(i + 1) % poly.size()])];
                if (cross2(prev, r, next) > 0) continue;  // convex
                if (samePoint(r, P)) continue;
                const bool inside = ccw ? inTriangle(r, M, I, P) : inTriangle(r, M, P, I);
                if (!inside) continue;
                const double dx = double(r.x) - M.x, dy = double(r.y) - M.y;
                const double angle = std::atan2(std::abs(dy), dx);
                const double dist = dx * dx + dy * dy;
                if (angle < bestAngle || (angle == bestAngle && dist < bestDist)) {
                    bestAngle = angle;
                    bestDist = dist;
                    bestVertex = i;
                }
            }
        }
    }
    std::vector<int> merged;
    merged.reserve(poly.size() + hole.size() + 2);
    merged.insert(merged.end(), poly.begin(), poly.begin() + long(bestVertex) + 1);
    for (size_t k = 0; k <= hole.size(); ++k) merged.push_back(hole[(mi + k) % hole.size()]);
    merged.push_back(poly[bestVertex]);
    merged.insert(merged.end(), poly.begin() + long(bestVertex) + 1, poly.end());
    poly.swap(merged);
}

}  // namespace

bool triangulatePolygon(const std::vector<Vec3>& points, const std::vector<int>& loopSizes,
                        std::vector<std::array<int, 3>>& triangles) {
    if (loopSizes.empty() || loopSizes[0] < 3) return false;
    const Projector proj(newellNormal(points.data(), loopSizes[0]));
    std::vector<Vec2> p(points.size());
    for (size_t i = 0; i < points.size(); ++i) p[i] = proj(points[i]);

    std::vector<int> poly(static_cast<size_t>(loopSizes[0]));
    for (int i = 0; i < loopSizes[0]; ++i) poly[size_t(i)] = i;
    std::vector<std::vector<int>> holes;
    for (size_t l = 1, start = size_t(loopSizes[0]); l < loopSizes.size(); start += size_t(loopSizes[l]), ++l) {
        if (loopSizes[l] < 3) continue;
        std::vector<int> h(static_cast<size_t>(loopSizes[l]));
        for (int i = 0; i < loopSizes[l]; ++i) h[size_t(i)] = int(start) + i;
        if (signedArea(p, h) > 0) std::reverse(h.begin(), h.end());
        holes.push_back(std::move(h));
    }
    // Bridge the holes right to left so earlier bridges never cross later ones.
    auto maxX = [&](const std::vector<int>& h) {
        float m = -kInfinity;
        for (int i : h) m = std::max(m, p[size_t(i)].x);
        return m;
    };
    std::sort(holes.begin(), holes.end(), [&](const auto& a, const auto& b) { return maxX(a) > maxX(b); });
    for (const auto& h : holes) bridgeHole(p, poly, h);

    // Ear clipping: repeatedly cut off a convex corner whose triangle holds
    // no other vertex of the remaining polygon.
    bool ok = true;
    std::vector<int> idx = poly;
    while (idx.size() > 3) {
        const size_t n = idx.size();
        size_t ear = n;
        bool degenerate = false;
        for (size_t i = 0; i < n && ear == n; ++i) {
            const Vec2& a = p[size_t(idx[(i + n - 1) % n])];
            const Vec2& b = p[size_t(idx[i])];
            const Vec2& c = p[size_t(idx[(i + 1) % n])];
            const double cr = cross2(a, b, c);
            if (cr < 0) continue;  // reflex
            bool blocked = false;
            for (size_t k = 0; k < n && !blocked; ++k) {
                if (k == i || k == (i + n - 1) % n || k == (i + 1) % n) continue;
                const Vec2& q = p[size_t(idx[k])];
                if (samePoint(q, a) || samePoint(q, b) || samePoint(q, c)) continue;
                blocked = inTriangle(q, a, b, c);
            }
            if (!blocked) {
                ear = i;
                degenerate = cr == 0;
            }
        }
        if (ear == n) {
            ok = false;  // self-intersecting: cut the first convex corner anyway
            for (size_t i = 0; i < n && ear == n; ++i)
                if (cross2(p[size_t(idx[(i + n - 1) % n])], p[size_t(idx[i])], p[size_t(idx[(i + 1) % n])]) > 0) ear = i;
            if (ear == n) break;
        }
        if (!degenerate)
            triangles.push_back({idx[(ear + n - 1) % n], idx[ear], idx[(ear + 1) % n]});
        idx.erase(idx.begin() + long(ear));
    }
    if (idx.size() == 3 && cross2(p[size_t(idx[0])], p[size_t(idx[1])], p[size_t(idx[2])]) > 0)
        triangles.push_back({idx[0], idx[1], idx[2]});
    return ok;
}

namespace {

PrimitivePtr makeTriangle(const std::shared_ptr<const scene::PrimitiveRecord>& record,
                          const std::shared_ptr<const SurfaceData>& data, const PolygonFaces& faces, int f, int a,
                          int b, int c) {
    const int cs = faces.faceCornerStart[size_t(f)];
    const int* v = faces.vertices.data() + cs;
    CornerRefs r;
    const int vv[4] = {v[a], v[b], v[c], v[c]};
    const int fv[4] = {cs + a, cs + b, cs + c, cs + c};
    for (int k = 0; k < 4; ++k) {
        r.vertex[k] = r.varying[k] = vv[k];
        r.faceVarying[k] = fv[k];
    }
    r.uniform = f;
    return std::make_unique<BilinearPatch>(record, data, r);
}

// Corners p, q, r, s in polygon order become bilinear corners 0, 1, 3, 2.
PrimitivePtr makeQuad(const std::shared_ptr<const scene::PrimitiveRecord>& record,
                      const std::shared_ptr<const SurfaceData>& data, const PolygonFaces& faces, int f, int p, int q,
                      int r, int s) {
    const int cs = faces.faceCornerStart[size_t(f)];
    const int* v = faces.vertices.data() + cs;
    CornerRefs refs;
    const int order[4] = {p, q, s, r};
    for (int k = 0; k < 4; ++k) {
        refs.vertex[k] = refs.varying[k] = v[order[k]];
        refs.faceVarying[k] = cs + order[k];
    }
    refs.uniform = f;
    return std::make_unique<BilinearPatch>(record, data, refs);
}

}  // namespace

bool appendFacePieces(const std::shared_ptr<const scene::PrimitiveRecord>& record,
                      const std::shared_ptr<const SurfaceData>& data, const PolygonFaces& faces, int f,
                      std::vector<PrimitivePtr>& out) {
    const int cs = faces.faceCornerStart[size_t(f)];
    const int n = faces.faceCornerStart[size_t(f) + 1] - cs;
    const int loops = faces.faceLoopStart[size_t(f) + 1] - faces.faceLoopStart[size_t(f)];
    if (n < 3 || loops < 1) return false;
    thread_local std::vector<Vec3> pts;
    pts.resize(size_t(n));
    for (int k = 0; k < n; ++k) pts[size_t(k)] = data->point(size_t(faces.vertices[size_t(cs + k)]));
    const int outline = faces.loopSize[size_t(faces.faceLoopStart[size_t(f)])];
    const Vec3 normal = newellNormal(pts.data(), outline);
    if (normal == Vec3(0.0f)) return false;

    if (loops == 1) {
        if (n == 3) {
            out.push_back(makeTriangle(record, data, faces, f, 0, 1, 2));
            return true;
        }
        const Projector proj(normal);
        bool convex = true;
        for (int k = 0; k < n && convex; ++k)
            convex = cross2(proj(pts[size_t((k + n - 1) % n)]), proj(pts[size_t(k)]), proj(pts[size_t((k + 1) % n)])) >= 0;
        if (convex) {
            // A fan of quads from corner 0, closed by a triangle when n is odd.
            int k = 1;
            for (; k + 2 <= n - 1; k += 2) out.push_back(makeQuad(record, data, faces, f, 0, k, k + 1, k + 2));
            if (k + 1 == n - 1) out.push_back(makeTriangle(record, data, faces, f, 0, k, k + 1));
            return true;
        }
    }
    std::vector<int> loopSizes(static_cast<size_t>(loops));
    for (int l = 0; l < loops; ++l) loopSizes[size_t(l)] = faces.loopSize[size_t(faces.faceLoopStart[size_t(f)] + l)];
    std::vector<std::array<int, 3>> tris;
    triangulatePolygon(std::vector<Vec3>(pts.begin(), pts.end()), loopSizes, tris);
    for (const auto& t : tris) out.push_back(makeTriangle(record, data, faces, f, t[0], t[1], t[2]));
    return !tris.empty();
}

PolygonMesh::PolygonMesh(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<const SurfaceData> data,
                         std::shared_ptr<const PolygonFaces> faces, int firstFace, int endFace)
    : Primitive(std::move(record)), m_data(std::move(data)), m_faces(std::move(faces)), m_first(firstFace),
      m_end(endFace) {
    const int c0 = m_faces->faceCornerStart[size_t(m_first)], c1 = m_faces->faceCornerStart[size_t(m_end)];
    for (int c = c0; c < c1; ++c) m_bound.extend(m_data->point(size_t(m_faces->vertices[size_t(c)])));
}

void PolygonMesh::split(bool splitU, std::vector<PrimitivePtr>& out) const {
    if (m_end - m_first > 1) {
        const int mid = m_first + (m_end - m_first) / 2;
        out.push_back(std::make_unique<PolygonMesh>(recordPtr(), m_data, m_faces, m_first, mid));
        out.push_back(std::make_unique<PolygonMesh>(recordPtr(), m_data, m_faces, mid, m_end));
        return;
    }
    appendFacePieces(recordPtr(), m_data, *m_faces, m_first, out);
}

Grid PolygonMesh::dice(int nu, int nv) const {
    UMBRA_CHECK(false, "PolygonMesh::dice called on a mesh that must be split first ({})", record().type);
    return {};
}

}  // namespace umbra::geometry
