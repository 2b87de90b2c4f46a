#pragma once
// The seven RenderMan quadrics (RI spec 3.2 §5.4), evaluated in closed form.
//
// All are surfaces of revolution about object-space z: a profile point q(v)
// swept by theta = u * thetamax, u and v in [0, 1] over the whole primitive
// (split pieces keep a sub-rectangle of that domain, so u, v, s, t stay
// continuous across pieces).
//
// Orientation: with positive thetamax and the v ranges as given in the spec
// (zmin < zmax, phimin < phimax, positive radius and height), dPdu x dPdv
// points *outward* (away from the z axis, or +z for the disk, away from the
// cone's axis and towards its apex side), which is RenderMan's "outside".
// A negative thetamax, reversed z/phi range or negative radius/height flips
// it, exactly as the parametrisation does. Grid::N holds the unit normal
// with the orientation of dPdu x dPdv, so Ng derived from P agrees with it.

#include "umbra/geometry/primitive.h"
#include "umbra/geometry/primvars.h"

namespace umbra::geometry {

/// The largest sweep angle a quadric keeps, in degrees: thetamax (and the
/// torus's phimin, phimax and their difference) beyond it are clamped with
/// a warning (docs/rib.md, "Limits").
constexpr float kMaxSweepDegrees = 360;

/// Which of the RI spec's quadric requests a QuadricShape describes.
enum class QuadricKind { Sphere, Cylinder, Cone, Disk, Paraboloid, Hyperboloid, Torus };

/// The shape parameters of one quadric, precomputed once per record
/// (angles in radians).
struct QuadricShape {
    QuadricKind kind = QuadricKind::Sphere;
    float thetaMax = 2 * kPi;
    float radius = 1;              // sphere, cylinder, cone, disk radius; paraboloid rmax; torus minor radius
    float majorRadius = 0;         // torus
    float z0 = 0, z1 = 0;          // cylinder/paraboloid z range; cone/disk height in z0
    float phi0 = 0, phi1 = 0;      // sphere and torus angle range
    float paraZMax = 1;            // paraboloid: the zmax that defines its profile (r = rmax sqrt(z / zmax))
    Vec3 p1, p2;                   // hyperboloid line
    float orient = 1;              // +1 when the closed-form normal has the direction of dPdu x dPdv

    /// Profile point (before rotation by theta) and its unnormalised normal at v.
    void profile(float v, Vec3* q, Vec3* n) const;
    /// Object-space point at (u, v).
    Vec3 point(float u, float v) const;
    /// Unit normal at (u, v), oriented as dPdu x dPdv.
    Vec3 normal(float u, float v) const;
    /// Bound of the part over `r` of the parametric domain.
    Bound3 bound(const ParamRange& r) const;
};

/// A quadric primitive (or a split piece of one).
class Quadric final : public Primitive {
public:
    Quadric(std::shared_ptr<const scene::PrimitiveRecord> record, const QuadricShape& shape,
            std::shared_ptr<const SurfaceData> data, const ParamRange& range = {});

    /// Builds the shape from a record's positional arguments; false (with an
    /// error naming the request and its argument list) when malformed.
    static bool shapeFromRecord(const scene::PrimitiveRecord& record, QuadricShape* shape, Diagnostics& diag);

    Bound3 bound() const override;
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    int splitsLeft(bool splitU) const override { return m_range.halvingsLeft(splitU); }
    Grid dice(int nu, int nv) const override;
    void dicePositions(int nu, int nv, std::vector<Vec3>& P) const override;

    const QuadricShape& shape() const { return m_shape; }
    const ParamRange& range() const { return m_range; }

private:
    void evalGrid(int nu, int nv, const std::vector<float>& a, const std::vector<float>& b, Vec3* P, Vec3* N) const;

    QuadricShape m_shape;
    std::shared_ptr<const SurfaceData> m_data;
    ParamRange m_range;
};

}  // namespace umbra::geometry
