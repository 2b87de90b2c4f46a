#include "umbra/geometry/polygon.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

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

/// Triangulation of a polygon with holes in O(n log n): a plane sweep
/// splits it into y-monotone pieces by diagonals (de Berg et al.,
/// "Computational Geometry", 3rd ed., ch. 3), each piece is cut into
/// triangles by the linear stack walk, and the result is accepted only
/// when its triangles, all counter-clockwise, add up to the polygon's
/// area. Vertices are ordered from top to bottom by (y, then x), which
/// settles horizontal edges and equal heights without special cases.
class SweepTriangulator {
public:
    SweepTriangulator(const std::vector<Vec2>& points, const std::vector<int>& loopSizes) {
        const size_t n = points.size();
        m_q.resize(n);
        for (size_t i = 0; i < n; ++i) m_q[i] = {double(points[i].x), double(points[i].y)};
        m_next.assign(n, -1);
        m_prev.assign(n, -1);
        double expected = 0;
        int start = 0;
        for (size_t l = 0; l < loopSizes.size(); start += loopSizes[l], ++l) {
            const int size = loopSizes[l];
            if (size < 3) continue;
            double area = 0;
            for (int k = 0; k < size; ++k) {
                const D2& a = m_q[size_t(start + k)];
                const D2& b = m_q[size_t(start + (k + 1) % size)];
                area += a.x * b.y - b.x * a.y;
            }
            area *= 0.5;
            // The outline runs counter-clockwise (the projection makes it
            // so), holes clockwise: the interior is always on the left.
            const bool reverse = l == 0 ? false : area > 0;
            if (l == 0 && area <= 0) m_valid = false;
            expected += l == 0 ? area : -std::abs(area);
            m_magnitude += std::abs(area);
            for (int k = 0; k < size; ++k) {
                const int v = start + k, w = start + (k + 1) % size;
                if (reverse) {
                    m_next[size_t(w)] = v;
                    m_prev[size_t(v)] = w;
                } else {
                    m_next[size_t(v)] = w;
                    m_prev[size_t(w)] = v;
                }
                m_events.push_back(v);
            }
        }
        m_expectedArea = expected;
    }

    /// False (and `triangles` untouched) when the input is not a simple
    /// polygon with holes inside it: crossing or repeated edges, holes
    /// outside or overlapping.
    bool run(std::vector<std::array<int, 3>>& triangles) {
        if (!m_valid || m_expectedArea <= 0) return false;
        std::sort(m_events.begin(), m_events.end(), [&](int a, int b) { return above(a, b); });
        if (!decompose()) return false;
        std::vector<std::array<int, 3>> out;
        out.reserve(m_events.size() + 2 * m_diagonals.size());
        if (!triangulatePieces(out)) return false;
        double sum = 0;
        for (const auto& t : out) sum += cross(t[0], t[1], t[2]);
        if (std::abs(0.5 * sum - m_expectedArea) > 1e-7 * m_magnitude) return false;
        triangles.insert(triangles.end(), out.begin(), out.end());
        return true;
    }

private:
    struct D2 {
        double x = 0, y = 0;
    };
    enum class Kind : unsigned char { Start, End, Split, Merge, Regular };

    /// Sweep order: higher first, then further left, then by index.
    bool above(int a, int b) const {
        const D2 &p = m_q[size_t(a)], &q = m_q[size_t(b)];
        if (p.y != q.y) return p.y > q.y;
        if (p.x != q.x) return p.x < q.x;
        return a < b;
    }
    double cross(int o, int a, int b) const { return cross(m_q[size_t(o)], m_q[size_t(a)], m_q[size_t(b)]); }
    static double cross(const D2& o, const D2& a, const D2& b) {
        return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    }

    /// Edges crossing the sweep line whose interior is on their right, left
    /// to right. An edge is named by its upper vertex e (it runs to m_next[e]).
    struct EdgeOrder {
        using is_transparent = void;
        const SweepTriangulator* t;
        // Side of point p against edge e: > 0 left of it, < 0 right.
        double side(int e, const D2& p) const {
            return cross(t->m_q[size_t(t->m_next[size_t(e)])], t->m_q[size_t(e)], p);
        }
        bool operator()(int e, int f) const {
            if (e == f) return false;
            // Compare where the younger edge (the lower upper vertex) starts.
            if (t->above(f, e)) {
                double s = side(f, t->m_q[size_t(e)]);
                if (s == 0) s = side(f, t->m_q[size_t(t->m_next[size_t(e)])]);
                return s != 0 ? s > 0 : e < f;
            }
            double s = side(e, t->m_q[size_t(f)]);
            if (s == 0) s = side(e, t->m_q[size_t(t->m_next[size_t(f)])]);
            return s != 0 ? s < 0 : e < f;
        }
        bool operator()(int e, const D2& p) const { return side(e, p) < 0; }
        bool operator()(const D2& p, int e) const { return side(e, p) > 0; }
    };
    using Status = std::set<int, EdgeOrder>;

    Kind kind(int v) const {
        const int u = m_prev[size_t(v)], w = m_next[size_t(v)];
        const bool uBelow = above(v, u), wBelow = above(v, w);
        const bool convex = cross(u, v, w) > 0;
        if (uBelow && wBelow) return convex ? Kind::Start : Kind::Split;
        if (!uBelow && !wBelow) return convex ? Kind::End : Kind::Merge;
        return Kind::Regular;
    }

    bool decompose() {
        const size_t n = m_q.size();
        std::vector<Kind> kinds(n, Kind::Regular);
        for (int v : m_events) kinds[size_t(v)] = kind(v);
        std::vector<int> helper(n, -1);
        std::vector<Status::iterator> where(n);
        std::vector<char> inStatus(n, 0);
        Status status(EdgeOrder{this});
        auto diagonal = [&](int a, int b) { m_diagonals.emplace_back(a, b); };
        auto insert = [&](int v) {
            auto [it, inserted] = status.insert(v);
            if (!inserted) return false;
            where[size_t(v)] = it;
            inStatus[size_t(v)] = 1;
            helper[size_t(v)] = v;
            return true;
        };
        // Ends the edge arriving at v from above, joining its helper if that is a merge vertex.
        auto finish = [&](int v) {
            const int e = m_prev[size_t(v)];
            if (!inStatus[size_t(e)]) return false;
            if (kinds[size_t(helper[size_t(e)])] == Kind::Merge) diagonal(v, helper[size_t(e)]);
            status.erase(where[size_t(e)]);
            inStatus[size_t(e)] = 0;
            return true;
        };
        // The edge directly left of v: v becomes its helper.
        auto leftOf = [&](int v, bool joinMerge, bool always) {
            auto it = status.lower_bound(m_q[size_t(v)]);
            if (it == status.begin()) return false;
            const int e = *std::prev(it);
            const int h = helper[size_t(e)];
            if (always || (joinMerge && kinds[size_t(h)] == Kind::Merge)) diagonal(v, h);
            helper[size_t(e)] = v;
            return true;
        };
        for (int v : m_events) {
            bool ok = true;
            switch (kinds[size_t(v)]) {
            case Kind::Start: ok = insert(v); break;
            case Kind::End: ok = finish(v); break;
            case Kind::Split: ok = leftOf(v, false, true) && insert(v); break;
            case Kind::Merge: ok = finish(v) && leftOf(v, true, false); break;
            case Kind::Regular:
                // Going down at v: the interior is on its right.
                if (above(m_prev[size_t(v)], v))
                    ok = finish(v) && insert(v);
                else
                    ok = leftOf(v, true, false);
                break;
            }
            if (!ok) return false;
        }
        return status.empty();
    }

    /// Cuts the polygon along the diagonals into faces and triangulates
    /// each. Half-edges leave each vertex sorted by angle; a face turns
    /// from each edge to the next one clockwise about the vertex reached.
    bool triangulatePieces(std::vector<std::array<int, 3>>& out) {
        struct Half {
            int from, to;
            bool interior;
            double angle;
        };
        std::vector<Half> halves;
        halves.reserve(2 * (m_events.size() + m_diagonals.size()));
        auto addEdge = [&](int a, int b, bool exteriorTwin) {
            const D2 &p = m_q[size_t(a)], &q = m_q[size_t(b)];
            const double angle = std::atan2(q.y - p.y, q.x - p.x);
            halves.push_back({a, b, true, angle});
            halves.push_back({b, a, !exteriorTwin, angle > 0 ? angle - M_PI : angle + M_PI});
        };
        for (int v : m_events) addEdge(v, m_next[size_t(v)], true);
        for (const auto& [a, b] : m_diagonals) addEdge(a, b, false);
        // Outgoing half-edges of each vertex, counter-clockwise by angle.
        const size_t n = m_q.size();
        std::vector<int> first(n + 1, 0);
        for (const Half& h : halves) ++first[size_t(h.from) + 1];
        for (size_t v = 0; v < n; ++v) first[v + 1] += first[v];
        std::vector<int> order(halves.size()), fill(first.begin(), first.end() - 1);
        for (size_t h = 0; h < halves.size(); ++h) order[size_t(fill[size_t(halves[h].from)]++)] = int(h);
        std::vector<int> position(halves.size());
        for (size_t v = 0; v < n; ++v) {
            auto b = order.begin() + first[v], e = order.begin() + first[v + 1];
            std::sort(b, e, [&](int x, int y) {
                return halves[size_t(x)].angle != halves[size_t(y)].angle ? halves[size_t(x)].angle < halves[size_t(y)].angle
                                                                         : x < y;
            });
            for (auto it = b; it != e; ++it) position[size_t(*it)] = int(it - order.begin());
        }
        // Half-edges come in twins: h ^ 1.
        auto nextHalf = [&](int h) {
            const int v = halves[size_t(h)].to;
            int k = position[size_t(h ^ 1)];
            k = k == first[size_t(v)] ? first[size_t(v) + 1] - 1 : k - 1;
            return order[size_t(k)];
        };
        std::vector<char> used(halves.size(), 0);
        std::vector<int> face;
        for (size_t h0 = 0; h0 < halves.size(); ++h0) {
            if (!halves[h0].interior || used[h0]) continue;
            face.clear();
            int h = int(h0);
            do {
                if (used[size_t(h)] || !halves[size_t(h)].interior || face.size() > halves.size()) return false;
                used[size_t(h)] = 1;
                face.push_back(halves[size_t(h)].from);
                h = nextHalf(h);
            } while (h != int(h0));
            if (!triangulateMonotone(face, out)) return false;
        }
        return true;
    }

    /// The stack walk over a y-monotone face given counter-clockwise.
    bool triangulateMonotone(const std::vector<int>& face, std::vector<std::array<int, 3>>& out) {
        const size_t k = face.size();
        if (k < 3) return false;
        size_t top = 0, bottom = 0;
        for (size_t i = 1; i < k; ++i) {
            if (above(face[i], face[top])) top = i;
            if (above(face[bottom], face[i])) bottom = i;
        }
        // Counter-clockwise from the top runs down the left chain.
        m_left.resize(std::max(m_left.size(), m_q.size()));
        for (size_t i = top; i != bottom; i = (i + 1) % k) m_left[size_t(face[i])] = 1;
        for (size_t i = bottom; i != top; i = (i + 1) % k) m_left[size_t(face[i])] = 0;
        m_sorted.assign(face.begin(), face.end());
        std::sort(m_sorted.begin(), m_sorted.end(), [&](int a, int b) { return above(a, b); });
        // Monotone: each chain must come out of the sort in its own order.
        auto emit = [&](int a, int b, int c) {
            const double area = cross(a, b, c);
            if (area > 0) out.push_back({a, b, c});
            else if (area < 0) out.push_back({a, c, b});
        };
        std::vector<int>& stack = m_stack;
        stack.assign({m_sorted[0], m_sorted[1]});
        for (size_t j = 2; j + 1 < k; ++j) {
            const int u = m_sorted[j];
            if (m_left[size_t(u)] != m_left[size_t(stack.back())]) {
                for (size_t i = 1; i < stack.size(); ++i) emit(u, stack[i - 1], stack[i]);
                stack.assign({m_sorted[j - 1], u});
                continue;
            }
            int last = stack.back();
            stack.pop_back();
            while (!stack.empty()) {
                const int s = stack.back();
                const bool inside = m_left[size_t(u)] ? cross(s, last, u) > 0 : cross(u, last, s) > 0;
                if (!inside) break;
                emit(u, last, s);
                last = s;
                stack.pop_back();
            }
            stack.push_back(last);
            stack.push_back(u);
        }
        const int u = m_sorted[k - 1];
        for (size_t i = 1; i < stack.size(); ++i) emit(u, stack[i - 1], stack[i]);
        return true;
    }

    std::vector<D2> m_q;
    std::vector<int> m_next, m_prev, m_events;
    std::vector<std::pair<int, int>> m_diagonals;
    std::vector<char> m_left;
    std::vector<int> m_sorted, m_stack;
    double m_expectedArea = 0, m_magnitude = 0;
    bool m_valid = true;
};

}  // namespace

bool triangulatePolygon(const std::vector<Vec3>& points, const std::vector<int>& loopSizes,
                        std::vector<std::array<int, 3>>& triangles) {
    if (loopSizes.empty() || loopSizes[0] < 3) return false;
    const Projector proj(newellNormal(points.data(), loopSizes[0]));
    std::vector<Vec2> p(points.size());
    for (size_t i = 0; i < points.size(); ++i) p[i] = proj(points[i]);

    size_t total = 0;
    for (int size : loopSizes) total += size >= 3 ? size_t(size) : 0;
    if (total > kEarClippingMaxVertices) {
        SweepTriangulator sweep(p, loopSizes);
        if (sweep.run(triangles)) return true;
        // Not a simple polygon: a fan over the outline keeps its winding
        // and its vertices, whatever area it then covers.
        for (int i = 1; i + 1 < loopSizes[0]; ++i) triangles.push_back({0, i, i + 1});
        return false;
    }

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
                      std::vector<PrimitivePtr>& out, Diagnostics* diag) {
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
    if (!triangulatePolygon(std::vector<Vec3>(pts.begin(), pts.end()), loopSizes, tris) && diag)
        diag->warningOnce("polygon-not-simple:" + record->loc.str(), record->loc,
                          "{}: face {} ({} vertices) is not a simple polygon (edges cross or repeat, or a hole lies "
                          "outside); it is drawn as {}", record->type, f, n,
                          n > int(kEarClippingMaxVertices) ? "a fan of triangles from its first vertex"
                                                           : "the triangles ear clipping found");
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
