#include "render/surface_pipeline.h"

#include "umbra/util/rng.h"

#include <chrono>
#include <cmath>

namespace umbra::render {

bool normalsFlip(const scene::Attributes& attrs, const Mat4& cameraFromObject) {
    // dPdu x dPdv measured in camera space is the family's outward normal
    // when cameraFromObject keeps handedness; a mirroring transform reverses
    // it, and so does an inside-out orientation (RI spec 3.2 §4.2).
    return attrs.insideOut != (cameraFromObject.det3() < 0);
}

SurfacePipeline::SurfacePipeline(FrameState& frame, const Pass& pass, Services& services, Diagnostics& diag,
                                 const film::Film& film)
    : m_frame(frame), m_pass(pass), m_services(services), m_diag(diag),
      m_rasterFromCamera(pass.camera.rasterFromCamera()) {
    // Pieces entirely outside the film's pixels and the filter margin are culled.
    float margin = float(film.filter().margin());
    m_rasterWindow[0] = float(film.x0()) - margin;
    m_rasterWindow[1] = float(film.x1()) + margin;
    m_rasterWindow[2] = float(film.y0()) - margin;
    m_rasterWindow[3] = float(film.y1()) + margin;
    dice::DiceParams eye;
    eye.nearClip = pass.camera.nearClip;
    m_eyeZ = dice::eyePlaneZ(eye);
}

Mat4 SurfacePipeline::cameraFromObject(const geometry::Primitive& prim) const {
    return m_pass.camera.cameraFromWorld * prim.record().worldFromObject;
}

dice::DiceParams SurfacePipeline::diceParams(const geometry::Primitive& prim) const {
    const hider::Camera& cam = m_pass.camera;
    const scene::Attributes& attrs = prim.attributes();
    dice::DiceParams p;
    p.cameraFromObject = cameraFromObject(prim);
    p.rasterFromCamera = m_rasterFromCamera;
    for (int i = 0; i < 4; ++i) p.rasterWindow[i] = m_rasterWindow[i];
    p.shadingRate = std::max(attrs.shadingRate, m_pass.minShadingRate);
    // A depth pass stores only depths, and a flat quad's are exact at any
    // size (1/z is linear across it): one micropolygon per piece. Other
    // surfaces dice no finer than the pass's flatness needs. Both unless a
    // displacement shader may bend the surface.
    if (m_pass.depthOnly && !m_frame.attributes.at(&attrs).displacement) {
        if (prim.flatQuad())
            p.shadingRate = kInfinity;
        else
            p.flatness = m_pass.flatness;
    }
    p.gridSize = m_frame.world->options.gridSize;
    p.nearClip = cam.nearClip;
    p.farClip = cam.farClip;
    p.maxEyeSplits = m_frame.world->options.eyeSplits;
    p.orthographic = !cam.perspective;
    p.binary = attrs.binaryDice;
    if (attrs.displacementBound > 0) {
        // The bound is in object units: the longest transformed axis scales it.
        const Mat4& c = p.cameraFromObject;
        float scale = std::max({length(c.vector({1, 0, 0})), length(c.vector({0, 1, 0})), length(c.vector({0, 0, 1}))});
        p.displacementBound = attrs.displacementBound * scale;
    }
    return p;
}

bool SurfacePipeline::takesPart(const scene::Attributes& attrs) const {
    return m_pass.depthOnly ? attrs.castsShadows : attrs.visibleToCamera;
}

Bound3 SurfacePipeline::rasterBound(const geometry::Primitive& prim) {
    // A primitive this pass never draws (Attribute "visibility") has no
    // bound, so it is culled whole instead of being split to grid size
    // first: a ground plane left out of a depth map costs nothing there.
    if (!takesPart(prim.attributes()) || prim.trimmedAway()) return {};
    dice::DiceParams p = diceParams(prim);
    Bound3 ob = prim.bound();
    if (dice::outsideView(dice::cameraBound(ob, p), p)) return {};
    return dice::rasterBound(ob, p);
}

hider::GeometryPipeline::Plan SurfacePipeline::plan(const geometry::Primitive& prim, int eyeSplits) {
    dice::DiceResult r = dice::decide(prim, prim.bound(), diceParams(prim), eyeSplits, &m_diag);
    Plan plan;
    plan.action = r.decision == dice::Decision::Dice    ? Action::Dice
                  : r.decision == dice::Decision::Split ? Action::Split
                                                        : Action::Cull;
    plan.splitU = r.splitU;
    plan.eyeSplit = r.eyeSplit;
    plan.nu = r.nu;
    plan.nv = r.nv;
    return plan;
}

bool SurfacePipeline::shade(const geometry::Primitive& prim, int nu, int nv, uint64_t id, hider::ShadedGrid& out) {
    const hider::Camera& cam = m_pass.camera;
    const scene::PrimitiveRecord& rec = prim.record();
    const scene::Attributes& attrs = *rec.attributes;
    if (!takesPart(attrs)) return false;

    Mat4 c = cameraFromObject(prim);
    const Mat4 objectFromCamera = c.inverse();
    geometry::ViewContext view;
    view.orthographic = !cam.perspective;
    view.eye = objectFromCamera.point({0, 0, 0});
    view.towardEye = normalize(objectFromCamera.vector({0, 0, -1}));
    geometry::Grid g = prim.diceInView(nu, nv, view);
    g.transform(c, objectFromCamera);
    // The family's own normals are outward; an inside-out primitive's point
    // in. User-supplied normals are used as given.
    if (g.ownNormals && attrs.insideOut)
        for (Vec3& n : g.N) n = -n;

    const PreparedAttributes& pa = m_frame.attributes.at(&attrs);
    const bool flip = normalsFlip(attrs, c);
    // A depth pass needs only positions; it runs the shading system just for
    // displacement.
    const std::vector<Vec3>* positions = &g.P;
    shading::ShadingGrid& sg = m_grids.local();
    if (!m_pass.depthOnly || pa.displacement) {
        GridState state{&m_frame, &m_pass, &rec, c};
        sg.resize(nu + 1, nv + 1);
        sg.flipNormals = flip;  // before bind(), which makes Ng
        sg.bind(g, attrs.color, attrs.opacity, cam.perspective);
        sg.seed = hashKeys(m_frame.frameSeed, uint32_t(id), uint32_t(id >> 32));
        sg.renderState = &state;

        shading::ShadeRequest request;
        request.displacement = pa.displacement.get();
        if (m_pass.depthOnly) {
            request.displacementOnly = true;
        } else {
            request.surface = pa.surface.get();
            request.atmosphere = pa.atmosphere.get();
            request.lights = pa.lights;
            request.outputs = m_frame.aovNames;
        }
        auto t0 = std::chrono::steady_clock::now();
        m_frame.shading->shade(sg, request, m_services);
        m_frame.shadingNanoseconds += uint64_t(
            std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count());
        positions = &sg.P;
    }
    const std::vector<Vec3>& P = *positions;

    const int n = (nu + 1) * (nv + 1);
    out.nu = nu;
    out.nv = nv;
    out.id = id;
    out.matte = attrs.matte;
    out.discs = g.discs;
    out.P.resize(size_t(n));
    out.bound = Bound3();
    bool anyInFront = false;
    for (int i = 0; i < n; ++i) {
        const Vec3& p = P[size_t(i)];
        if (cam.perspective && p.z < m_eyeZ) {
            // Displaced behind the eye: keep it out of the image.
            out.P[size_t(i)] = {0, 0, -kInfinity};
            continue;
        }
        out.P[size_t(i)] = cam.rasterOf(p);
        out.bound.extend(out.P[size_t(i)]);
        anyInFront = true;
    }
    if (!anyInFront) return false;

    out.trim = prim.trimRegion();
    out.uv.clear();
    if (out.trim) {
        out.uv.resize(size_t(n) * 2);
        for (int i = 0; i < n; ++i) {
            out.uv[size_t(2 * i)] = g.u[size_t(i)];
            out.uv[size_t(2 * i + 1)] = g.v[size_t(i)];
        }
    }
    out.culled.clear();
    if (attrs.sides == 1 && m_pass.cull != Pass::Cull::None && !cullFacing(P, flip, out)) return false;

    out.ownSecondLayer = m_pass.depthOnly && m_pass.openSurfacesAreOwnSecondLayer && attrs.sides == 2;
    if (m_pass.depthOnly) {
        out.Ci.clear();
        out.Oi.clear();
        out.aovFloats = 0;
        return true;
    }
    out.Ci.assign(sg.Ci.begin(), sg.Ci.begin() + n);
    out.Oi.assign(sg.Oi.begin(), sg.Oi.begin() + n);
    fillAovs(sg, out);
    return true;
}

bool SurfacePipeline::cullFacing(const std::vector<Vec3>& P, bool flip, hider::ShadedGrid& out) const {
    // A micropolygon faces the eye when its outward normal points at it:
    // dPdu x dPdv in camera space, negated when normalsFlip() says so.
    const int nu = out.nu, nv = out.nv, nu1 = nu + 1;
    const bool perspective = m_pass.camera.perspective;
    const bool dropFront = m_pass.cull == Pass::Cull::Front;
    out.culled.assign(size_t(nu) * size_t(nv), 0);
    bool anyKept = false;
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            // The cross of the diagonals, (a+b) x (b-a) = 2 a x b, stays
            // right where one edge collapses (a sphere's pole).
            const Vec3& a = P[size_t(j * nu1 + i)];
            const Vec3& d = P[size_t((j + 1) * nu1 + i + 1)];
            Vec3 n = cross(d - a, P[size_t((j + 1) * nu1 + i)] - P[size_t(j * nu1 + i + 1)]);
            Vec3 centre = (a + d) * 0.5f;
            float toward = perspective ? dot(n, centre) : n.z;  // > 0: faces away (unflipped)
            bool front = flip ? toward > 0 : toward < 0;
            bool drop = dropFront ? front : !front;
            out.culled[size_t(j * nu + i)] = drop ? 1 : 0;
            anyKept |= !drop;
        }
    if (!anyKept) return false;
    return true;
}

void SurfacePipeline::fillAovs(const shading::ShadingGrid& sg, hider::ShadedGrid& out) const {
    int total = 0;
    for (int c : m_frame.aovComponents) total += c;
    out.aovFloats = total;
    if (total == 0) {
        out.aov.clear();
        return;
    }
    const int n = sg.size();
    out.aov.assign(size_t(n) * size_t(total), 0.0f);
    std::vector<float> values;
    int offset = 0;
    for (size_t k = 0; k < m_frame.aovNames.size(); ++k) {
        const std::string& name = m_frame.aovNames[k];
        const int comps = m_frame.aovComponents[k];
        auto put = [&](int i, const float* v, int count) {
            for (int c = 0; c < comps; ++c) out.aov[size_t(i) * total + offset + c] = v[std::min(c, count - 1)];
        };
        auto putVec = [&](const std::vector<Vec3>& src) {
            for (int i = 0; i < n; ++i) put(i, &src[size_t(i)].x, 3);
        };
        auto putFloat = [&](const std::vector<float>& src) {
            for (int i = 0; i < n; ++i) put(i, &src[size_t(i)], 1);
        };
        int fpv = 0;
        if (sg.output(name, &values, &fpv) && fpv > 0) {
            bool uniform = values.size() == size_t(fpv);
            for (int i = 0; i < n; ++i) put(i, values.data() + (uniform ? 0 : size_t(i) * fpv), fpv);
        } else if (name == "Ci") putVec(sg.Ci);
        else if (name == "Oi") putVec(sg.Oi);
        else if (name == "P") putVec(sg.P);
        else if (name == "N") putVec(sg.N);
        else if (name == "Ng") putVec(sg.Ng);
        else if (name == "Cs") putVec(sg.Cs);
        else if (name == "Os") putVec(sg.Os);
        else if (name == "I") putVec(sg.I);
        else if (name == "dPdu") putVec(sg.dPdu);
        else if (name == "dPdv") putVec(sg.dPdv);
        else if (name == "s") putFloat(sg.s);
        else if (name == "t") putFloat(sg.t);
        else if (name == "u") putFloat(sg.u);
        else if (name == "v") putFloat(sg.v);
        else if (name == "z") {
            for (int i = 0; i < n; ++i) put(i, &sg.P[size_t(i)].z, 1);
        }
        offset += comps;
    }
}

}  // namespace umbra::render
