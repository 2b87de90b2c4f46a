#pragma once
// Deformation blur for every family: one primitive per shape of a
// MotionBegin block around a primitive request, split in lockstep, so each
// piece knows its surface at every shape time (Primitive::diceShape).

#include "umbra/geometry/primitive.h"

namespace umbra::geometry {

/// The same surface at several times: shapes[k] is the primitive made from
/// shape k's record (same type and topology). Bound, split and dice follow
/// shape 0, whose record carries the shape times.
class DeformingPrimitive final : public Primitive {
public:
    explicit DeformingPrimitive(std::vector<PrimitivePtr> shapes);

    Bound3 bound() const override { return m_bound; }
    /// Splits every shape the same way and pairs the pieces up. Families
    /// split by parameter or face, so the pieces correspond; a face whose
    /// shapes triangulate into different numbers of pieces (a non-convex
    /// polygon turning convex) keeps shape 0 only, and `lostShapes` counts it.
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    int splitsLeft(bool splitU) const override;
    bool diceable() const override { return m_shapes[0]->diceable(); }
    Grid dice(int nu, int nv) const override { return m_shapes[0]->dice(nu, nv); }
    Grid diceInView(int nu, int nv, const ViewContext& view) const override {
        return m_shapes[0]->diceInView(nu, nv, view);
    }
    bool fixedCounts(int* nu, int* nv) const override { return m_shapes[0]->fixedCounts(nu, nv); }
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override { m_shapes[0]->dicePositions(nu, nv, P); }
    void dicePositionsInView(int nu, int nv, const ViewContext& view, std::vector<Vec3>& P) const override {
        m_shapes[0]->dicePositionsInView(nu, nv, view, P);
    }
    bool flatQuad() const override;
    std::shared_ptr<const TrimRegion> trimRegion() const override { return m_shapes[0]->trimRegion(); }
    bool trimmedAway() const override { return m_shapes[0]->trimmedAway(); }
    int shapeCount() const override { return int(m_shapes.size()); }
    void diceShape(int shape, int nu, int nv, const ViewContext& view, std::vector<Vec3>& P) const override;

    /// Pieces split so far whose shapes could not be paired (see split()).
    static uint64_t lostShapes();

private:
    std::vector<PrimitivePtr> m_shapes;
    Bound3 m_bound;
};

}  // namespace umbra::geometry
