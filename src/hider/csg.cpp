#include "umbra/hider/csg.h"

#include "umbra/util/error.h"

namespace umbra::hider {

int CsgForest::add(Op op, int parent) {
    const int node = int(m_op.size());
    UMBRA_CHECK(parent >= -1 && parent < node, "CSG node {} given parent {}", node, parent);
    m_op.push_back(op);
    m_parent.push_back(parent);
    m_root.push_back(parent < 0 ? node : m_root[size_t(parent)]);
    m_firstChild.push_back(-1);
    m_childCount.push_back(0);
    if (parent >= 0) {
        if (m_firstChild[size_t(parent)] < 0) m_firstChild[size_t(parent)] = node;
        ++m_childCount[size_t(parent)];
    }
    return node;
}

bool CsgForest::evaluate(int node, const CsgRayState& state) const {
    const size_t n = size_t(node);
    switch (m_op[n]) {
    case Op::Primitive:
        return state.own[n] || state.count[n] > 0;
    case Op::Union:
        return state.count[n] > 0;
    case Op::Intersection:
        // An empty intersection is empty, not everything.
        return m_childCount[n] > 0 && state.count[n] == m_childCount[n];
    case Op::Difference:
        return m_firstChild[n] >= 0 && state.in[size_t(m_firstChild[n])] && state.count[n] == 0;
    }
    return false;
}

bool CsgForest::setLeaf(int leaf, bool inside, CsgRayState& state) const {
    state.own[size_t(leaf)] = inside;
    int node = leaf;
    for (;;) {
        const bool now = evaluate(node, state);
        if (now == bool(state.in[size_t(node)])) return false;
        state.in[size_t(node)] = now;
        const int parent = m_parent[size_t(node)];
        if (parent < 0) return true;
        // A difference's first child is read through `in`; the others count.
        if (!(m_op[size_t(parent)] == Op::Difference && m_firstChild[size_t(parent)] == node))
            state.count[size_t(parent)] += now ? 1 : -1;
        node = parent;
    }
}

void CsgForest::clearPath(int leaf, CsgRayState& state) const {
    for (int node = leaf; node >= 0; node = m_parent[size_t(node)]) {
        state.count[size_t(node)] = 0;
        state.own[size_t(node)] = 0;
        state.in[size_t(node)] = 0;
    }
}

}  // namespace umbra::hider
