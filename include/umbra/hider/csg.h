#pragma once
// Constructive solid geometry (RI spec 3.2 §5.8, SolidBegin/SolidEnd) as the
// hider resolves it: per sample, along the ray.
//
// Terms: a *solid* is a node of a CSG tree. A *leaf* is a "primitive" solid:
// the closed surfaces given inside it bound one volume. An operation node
// ("union", "intersection", "difference") combines its children; difference
// subtracts every child after the first from the first.
//
// A sample keeps every hit of a CSG tree's surfaces, each marked entering or
// leaving its leaf (the surface faces toward or away from the eye). Along
// the ray, a leaf is inside just after a hit when its next hit leaves it
// (or, with no later hit, when this one enters); the tree's expression
// gives whether the ray is inside the result. A hit at which that answer
// changes lies on the result's boundary: it is a visible surface; every
// other hit is not (SampleBuffer::resolveCsg).

#include <cstddef>
#include <cstdint>
#include <vector>

namespace umbra::hider {

/// Where one ray is, node by node, while its hits are walked: whether it is
/// inside each node's result and, per node, how many children count toward
/// it. All zero (outside everything) to begin with; CsgForest::setLeaf keeps
/// it consistent.
struct CsgRayState {
    std::vector<int32_t> count;  // children inside (difference: after the first)
    std::vector<uint8_t> own;    // a leaf: inside its own surfaces
    std::vector<uint8_t> in;     // inside the node's result

    void reset(size_t nodes) {
        count.assign(nodes, 0);
        own.assign(nodes, 0);
        in.assign(nodes, 0);
    }
};

/// The CSG trees of a world: nodes in the order their SolidBegin came (a
/// parent before its children), each with its operation and parent (-1 for a
/// tree's root).
class CsgForest {
public:
    enum class Op : uint8_t { Primitive, Union, Intersection, Difference };

    /// Appends a node; returns its index. `parent` must be an earlier node or -1.
    int add(Op op, int parent);
    bool empty() const { return m_op.empty(); }
    int size() const { return int(m_op.size()); }
    Op op(int node) const { return m_op[size_t(node)]; }
    /// The root of the tree holding `node`.
    int root(int node) const { return m_root[size_t(node)]; }
    /// Sets whether the ray is inside leaf `leaf`'s own surfaces and updates
    /// the nodes above it, stopping where nothing changes: the cost is the
    /// leaf's depth at most, however large the tree. True when the root's
    /// answer changed (the hit lies on the result's boundary). A
    /// "primitive" node is also inside its children (nested primitive
    /// blocks are one solid); an operation node has no surfaces of its own.
    bool setLeaf(int leaf, bool inside, CsgRayState& state) const;
    /// Returns the nodes from `leaf` up to its root to the all-outside state.
    void clearPath(int leaf, CsgRayState& state) const;

private:
    bool evaluate(int node, const CsgRayState& state) const;

    std::vector<Op> m_op;
    std::vector<int> m_parent, m_root, m_firstChild, m_childCount;
};

}  // namespace umbra::hider
