#include "umbra/geometry/deforming.h"

#include <algorithm>
#include <atomic>

namespace umbra::geometry {

namespace {
std::atomic<uint64_t> g_lostShapes{0};
}

DeformingPrimitive::DeformingPrimitive(std::vector<PrimitivePtr> shapes)
    : Primitive(shapes.at(0)->recordPtr()), m_shapes(std::move(shapes)) {
    for (const PrimitivePtr& s : m_shapes) m_bound.extend(s->bound());
}

int DeformingPrimitive::splitsLeft(bool splitU) const {
    int n = kManySplits;
    for (const PrimitivePtr& s : m_shapes) n = std::min(n, s->splitsLeft(splitU));
    return n;
}

void DeformingPrimitive::split(bool splitU, std::vector<PrimitivePtr>& out) const {
    std::vector<std::vector<PrimitivePtr>> pieces(m_shapes.size());
    for (size_t k = 0; k < m_shapes.size(); ++k) m_shapes[k]->split(splitU, pieces[k]);
    bool paired = true;
    for (size_t k = 1; k < pieces.size(); ++k) paired &= pieces[k].size() == pieces[0].size();
    if (!paired) {
        g_lostShapes.fetch_add(1, std::memory_order_relaxed);
        for (PrimitivePtr& p : pieces[0]) out.push_back(std::move(p));
        return;
    }
    for (size_t i = 0; i < pieces[0].size(); ++i) {
        std::vector<PrimitivePtr> shapes;
        for (auto& shapePieces : pieces) shapes.push_back(std::move(shapePieces[i]));
        out.push_back(std::make_unique<DeformingPrimitive>(std::move(shapes)));
    }
}

bool DeformingPrimitive::flatQuad() const {
    for (const PrimitivePtr& s : m_shapes)
        if (!s->flatQuad()) return false;
    return true;
}

void DeformingPrimitive::diceShape(int shape, int nu, int nv, const ViewContext& view, std::vector<Vec3>& P) const {
    m_shapes[size_t(shape)]->diceShape(0, nu, nv, view, P);
}

uint64_t DeformingPrimitive::lostShapes() { return g_lostShapes.load(std::memory_order_relaxed); }

}  // namespace umbra::geometry
