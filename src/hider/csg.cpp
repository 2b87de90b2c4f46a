#include "umbra/hider/csg.h"

#include "umbra/util/error.h"

namespace umbra::hider {

int CsgForest::add(Op op, int parent) {
    const int node = int(m_op.size());
    UMBRA_CHECK(parent >= -1 && parent < node, "CSG node {} given parent {}", node, parent);
    m_op.push_back(op);
    m_parent.push_back(parent);
    m_root.push_back(parent < 0 ? node : m_root[size_t(parent)]);
    m_children.emplace_back();
    if (parent >= 0) m_children[size_t(parent)].push_back(node);
    return node;
}

bool CsgForest::inside(int node, const int32_t* inLeaf) const {
    const std::vector<int>& children = m_children[size_t(node)];
    switch (m_op[size_t(node)]) {
    case Op::Primitive: {
        if (inLeaf[node] > 0) return true;
        for (int c : children)
            if (inside(c, inLeaf)) return true;
        return false;
    }
    case Op::Union:
        for (int c : children)
            if (inside(c, inLeaf)) return true;
        return false;
    case Op::Intersection:
        // An empty intersection is empty, not everything.
        if (children.empty()) return false;
        for (int c : children)
            if (!inside(c, inLeaf)) return false;
        return true;
    case Op::Difference:
        if (children.empty() || !inside(children.front(), inLeaf)) return false;
        for (size_t k = 1; k < children.size(); ++k)
            if (inside(children[k], inLeaf)) return false;
        return true;
    }
    return false;
}

}  // namespace umbra::hider
