#include "render/surface_pipeline.h"

#include "umbra/util/cpu_time.h"
#include "umbra/util/rng.h"

#include <algorithm>
#include <cmath>

namespace umbra::render {

const PreparedAttributes& FrameState::prepared(const scene::Attributes& attrs) const {
    if (auto it = attributes.find(&attrs); it != attributes.end()) return it->second;
    std::lock_guard<std::mutex> lock(lateMutex);
    std::unique_ptr<LateAttributes>& entry = late[&attrs];
    if (!entry) entry = std::make_unique<LateAttributes>();
    PreparedAttributes& pa = entry->prepared;
    if (!entry->shaded) {
        pa.attributes = &attrs;
        if (prepareLate) prepareLate(pa);
        entry->shaded = true;
    }
    // Depth passes need no lights; the camera pass, which starts after the
    // lights are made, gets them here before any of its grids uses them.
    if (!entry->lit && lights) {
        for (int l : attrs.lights)
            if (l >= 0 && size_t(l) < lights->size() && (*lights)[size_t(l)]) pa.lights.push_back((*lights)[size_t(l)].get());
        entry->lit = true;
    }
    return pa;
}

bool normalsFlip(const scene::Attributes& attrs, const Mat4& cameraFromObject) {
    // dPdu x dPdv measured in camera space is the family's outward normal
    // when cameraFromObject keeps handedness; a mirroring transform reverses
    // it, and so does an inside-out orientation (RI spec 3.2 §4.2).
    return attrs.insideOut != (cameraFromObject.det3() < 0);
}

float rasterDetail(const std::array<Vec3, 8>& worldCorners, const hider::Camera& camera, float relativeDetail) {
    float x0 = kInfinity, y0 = kInfinity, x1 = -kInfinity, y1 = -kInfinity;
    for (const Vec3& w : worldCorners) {
        const Vec3 c = camera.cameraFromWorld.point(w);
        if (camera.perspective && !(c.z > 0)) return kInfinity;
        const Vec3 r = camera.rasterOf(c);
        x0 = std::min(x0, r.x);
        x1 = std::max(x1, r.x);
        y0 = std::min(y0, r.y);
        y1 = std::max(y1, r.y);
    }
    return (x1 - x0) * (y1 - y0) * relativeDetail;
}

std::pair<float, float> dissolveWindow(float detail, const std::array<float, 4>& range) {
    const float minVisible = range[0], lower = range[1], upper = range[2], maxVisible = range[3];
    // An infinite maxvisible keeps even an infinite detail (a box around the eye).
    if (!(detail >= minVisible) || (detail >= maxVisible && maxVisible < kInfinity)) return {0.0f, 0.0f};
    if (detail < lower) return {1.0f - (detail - minVisible) / (lower - minVisible), 1.0f};
    if (detail >= upper && upper < kInfinity) return {0.0f, std::min(1.0f, (maxVisible - detail) / (maxVisible - upper))};
    return {0.0f, 1.0f};
}

SurfacePipeline::SurfacePipeline(FrameState& frame, const Pass& pass, Services& services, Diagnostics& diag,
                                 const film::Film& film)
    : m_frame(frame), m_pass(pass), m_services(services), m_diag(diag),
      m_rasterFromCamera(pass.camera.rasterFromCamera()) {
    // Pieces entirely outside the film's pixels and the filter margin are culled.
    float margin = float(film.filterMargin());
    m_rasterWindow[0] = float(film.x0()) - margin;
    m_rasterWindow[1] = float(film.x1()) + margin;
    m_rasterWindow[2] = float(film.y0()) - margin;
    m_rasterWindow[3] = float(film.y1()) + margin;
    dice::DiceParams eye;
    eye.nearClip = pass.camera.nearClip;
    m_eyeZ = dice::eyePlaneZ(eye);
}

namespace {

/// The most one chord of a moving piece's path may turn: a sixteenth of a
/// half turn keeps a point on a circle within 0.5% of its radius.
constexpr float kMaxChordTurn = kPi / 16;
/// Placement times per piece at most (memory: a position array each).
constexpr size_t kMaxPlacementTimes = 33;

}  // namespace

Mat4 SurfacePipeline::cameraFromObject(const geometry::Primitive& prim) const {
    const scene::PrimitiveRecord& rec = prim.record();
    if (m_pass.cameraMotion || rec.worldFromObjectMotion) return cameraFromObjectAt(rec, m_frame.shutterOpen);
    return m_pass.camera.cameraFromWorld * rec.worldFromObject;
}

Mat4 SurfacePipeline::cameraFromObjectAt(const scene::PrimitiveRecord& rec, float t) const {
    const Mat4 cameraFromWorld = m_pass.cameraMotion ? m_pass.cameraMotion->at(t) : m_pass.camera.cameraFromWorld;
    const Mat4 worldFromObject = rec.worldFromObjectMotion ? rec.worldFromObjectMotion->at(t) : rec.worldFromObject;
    return cameraFromWorld * worldFromObject;
}

void SurfacePipeline::placementTimes(const geometry::Primitive& prim, std::vector<float>& times) const {
    const float open = m_frame.shutterOpen, close = m_frame.shutterClose;
    const scene::PrimitiveRecord& rec = prim.record();
    times.assign(1, open);
    const bool moves = rec.worldFromObjectMotion || m_pass.cameraMotion || prim.shapeCount() > 1;
    if (!m_frame.motionBlur() || !moves) return;
    std::vector<float> keys;
    if (rec.worldFromObjectMotion) keys = rec.worldFromObjectMotion->keyTimes();
    if (m_pass.cameraMotion)
        for (float t : m_pass.cameraMotion->keyTimes()) keys.push_back(t);
    if (prim.shapeCount() > 1) keys.insert(keys.end(), rec.shapeTimes.begin(), rec.shapeTimes.end());
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    for (float t : keys)
        if (t > open && t < close) times.push_back(t);
    times.push_back(close);
    // Chords along turning paths.
    std::vector<float> fine{times[0]};
    for (size_t k = 1; k < times.size(); ++k) {
        const float a = times[k - 1], b = times[k];
        float turn = 0;
        if (rec.worldFromObjectMotion) turn = rec.worldFromObjectMotion->turnBetween(a, b);
        if (m_pass.cameraMotion) turn = std::max(turn, m_pass.cameraMotion->turnBetween(a, b));
        // A Rotate block keyed past a half turn turns as far as it says
        // (TransformRequest): up to the placements' cap in one interval.
        const int pieces = std::clamp(int(std::ceil(turn / kMaxChordTurn)), 1, int(kMaxPlacementTimes) - 1);
        for (int i = 1; i < pieces; ++i) fine.push_back(a + (b - a) * float(i) / float(pieces));
        fine.push_back(b);
    }
    if (fine.size() > kMaxPlacementTimes) {  // keep the ends, thin the rest evenly
        std::vector<float> thinned;
        for (size_t i = 0; i < kMaxPlacementTimes; ++i)
            thinned.push_back(fine[(i * (fine.size() - 1)) / (kMaxPlacementTimes - 1)]);
        fine = std::move(thinned);
    }
    times = std::move(fine);
}

Bound3 SurfacePipeline::sweptBound(const geometry::Primitive& prim, const dice::DiceParams& p,
                                   const std::vector<float>& times) const {
    Bound3 b;
    dice::DiceParams at = p;
    for (float t : times) {
        at.cameraFromObject = cameraFromObjectAt(prim.record(), t);
        const Bound3 cb = dice::cameraBound(prim, at);
        if (!cb.empty()) b.extend(cb);
    }
    return b;
}

float SurfacePipeline::displacementAllowance(const scene::Attributes& attrs, const Mat4& cameraFromObject) const {
    // The bound is in its "coordinatesystem" (object space by default): the
    // longest axis of that space, in camera space, scales it.
    if (!(attrs.displacementBound > 0)) return 0;
    const Mat4& cameraFromWorld = m_pass.camera.cameraFromWorld;
    const std::string& space = attrs.displacementBoundSpace;
    Mat4 c = cameraFromObject;
    if (space == "world") {
        c = cameraFromWorld;
    } else if (space == "camera" || space == "current") {
        c = Mat4::identity();
    } else if (space == "shader" && attrs.displacement) {
        c = cameraFromWorld * attrs.displacement->worldFromShader;
    } else if (space != "object") {
        if (const Mat4* named = attrs.space(space, m_frame.world->coordinateSystems)) c = cameraFromWorld * *named;
    }
    const float scale =
        std::max({length(c.vector({1, 0, 0})), length(c.vector({0, 1, 0})), length(c.vector({0, 0, 1}))});
    return attrs.displacementBound * scale;
}

float SurfacePipeline::confusionRadius(float z) const {
    const hider::Camera& cam = m_pass.camera;
    if (!(m_pass.lensRadius > 0) || !cam.perspective) return 0;
    const float scale = cam.maxProjectedScale() / cam.tanHalfFov;
    return m_pass.lensRadius * scale * std::abs(1.0f / m_pass.focalDistance - 1.0f / z);
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
    if (m_pass.depthOnly && !m_frame.prepared(attrs).displacement) {
        if (prim.flatQuad())
            p.shadingRate = kInfinity;
        else
            p.flatness = m_pass.flatness;
    }
    // GeometricApproximation "flatness": dice finer where curvature needs it
    // (a floor on the counts; the depth pass's own flatness is a ceiling).
    static const std::string kFlatness = "GeometricApproximation:flatness";
    const auto fl = attrs.user.find(kFlatness);
    if (fl != attrs.user.end() && !fl->second.floats.empty() && fl->second.floats[0] > 0)
        p.maxStandOff = fl->second.floats[0];
    p.gridSize = m_frame.world->options.gridSize;
    p.nearClip = cam.nearClip;
    p.farClip = cam.farClip;
    p.maxEyeSplits = m_frame.world->options.eyeSplits;
    p.orthographic = !cam.perspective;
    p.binary = attrs.binaryDice;
    p.displacementBound = displacementAllowance(attrs, p.cameraFromObject);
    thread_local std::vector<float> times;
    placementTimes(prim, times);
    const bool lens = m_pass.lensRadius > 0 && cam.perspective;
    if (times.size() > 1 || lens) {
        const Bound3 cb = times.size() > 1 ? sweptBound(prim, p, times) : dice::cameraBound(prim, p);
        if (times.size() > 1) p.sweep = cb;
        // What blurs into the image from outside it is not culled: the
        // window grows by the bound's largest circle of confusion, and a
        // grid's shading rate by "motionfactor" for fast or defocused
        // pieces (PRMan's rule: rate x motionfactor x blur / 16 pixels).
        float blur = 0;
        if (lens && !cb.empty() && cb.max.z > m_eyeZ) {
            blur = std::max(confusionRadius(std::max(cb.min.z, m_eyeZ)), confusionRadius(cb.max.z));
            if (cb.min.z <= m_eyeZ) blur = kInfinity;
            for (int i = 0; i < 4; ++i) p.rasterWindow[i] += (i & 1) ? blur : -blur;
        }
        const auto mf = attrs.user.find("GeometricApproximation:motionfactor");
        const float motionFactor = mf != attrs.user.end() && !mf->second.floats.empty() ? mf->second.floats[0] : 0.0f;
        if (motionFactor > 0 && !cb.empty() && cb.min.z > m_eyeZ) {
            // The blur length: the path of the bound's centre on screen,
            // plus the circle of confusion's diameter.
            float path = 0;
            Vec3 prev;
            dice::DiceParams at = p;
            const Bound3 ob = prim.bound();
            for (size_t k = 0; k < times.size(); ++k) {
                at.cameraFromObject = cameraFromObjectAt(prim.record(), times[k]);
                const Bound3 rb = dice::rasterBound(ob, at);
                const Vec3 centre = (rb.min + rb.max) * 0.5f;
                if (k > 0) path += std::hypot(centre.x - prev.x, centre.y - prev.y);
                prev = centre;
            }
            const float length = path + 2.0f * std::min(blur, 1e6f);
            if (std::isfinite(length)) p.shadingRate *= std::max(1.0f, motionFactor * length / 16.0f);
        }
    }
    return p;
}

bool SurfacePipeline::takesPart(const scene::Attributes& attrs) const {
    if (!(m_pass.depthOnly ? attrs.castsShadows : attrs.visibleToCamera)) return false;
    if (!attrs.hasDetail) return true;
    // Attribute sets a procedural made while a pass ran are prepared late.
    const PreparedAttributes& pa = m_frame.prepared(attrs);
    return pa.dissolveBelow > pa.dissolveFrom;  // some level of detail draws it
}

Bound3 SurfacePipeline::rasterBound(const geometry::Primitive& prim) {
    // A primitive this pass never draws (Attribute "visibility") has no
    // bound, so it is culled whole instead of being split to grid size
    // first: a ground plane left out of a depth map costs nothing there.
    if (!takesPart(prim.attributes()) || prim.trimmedAway()) return {};
    dice::DiceParams p = diceParams(prim);
    const Bound3 cb = p.sweep.empty() ? dice::cameraBound(prim, p) : p.sweep;
    if (dice::outsideView(cb, p)) return {};
    Bound3 r = dice::rasterBoundOfCamera(cb, p);
    if (m_pass.lensRadius > 0 && m_pass.camera.perspective && std::isfinite(r.min.x)) {
        const float blur = std::max(confusionRadius(std::max(cb.min.z, m_eyeZ)), confusionRadius(cb.max.z));
        r.min.x -= blur;
        r.min.y -= blur;
        r.max.x += blur;
        r.max.y += blur;
    }
    return r;
}

hider::GeometryPipeline::Plan SurfacePipeline::plan(const geometry::Primitive& prim, int eyeSplits,
                                                    double splitBudget, double need) {
    dice::DiceParams p = diceParams(prim);
    p.splitBudget = splitBudget;
    p.pieceNeed = need;
    dice::DiceResult r = dice::decide(prim, p, eyeSplits, &m_diag);
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

double SurfacePipeline::rasterNeed(const geometry::Primitive& prim, const Bound3& rasterBound) {
    dice::DiceParams p = diceParams(prim);
    const double measured = measuredNeed(prim, p);
    // The cap on the frame's own window, not the one a lens widens (which
    // can be infinite).
    std::copy(m_rasterWindow, m_rasterWindow + 4, p.rasterWindow);
    const double bounded = dice::boundNeed(rasterBound, p);
    return measured >= 0 ? std::min(measured, bounded) : bounded;
}

double SurfacePipeline::measuredNeed(const geometry::Primitive& prim, dice::DiceParams p) const {
    if (p.sweep.empty()) return dice::rasterNeed(prim, p);
    // A moving piece: the mean of its needs at its placement times (its
    // shape at the shutter's opening, placed at each). The mean, not the
    // most: pieces of a surface that cross the frame's edge in turn add
    // up to their parent then, as still ones do.
    thread_local std::vector<float> times;
    placementTimes(prim, times);
    p.sweep = Bound3{};
    double sum = 0;
    for (const float t : times) {
        p.cameraFromObject = cameraFromObjectAt(prim.record(), t);
        const double need = dice::rasterNeed(prim, p);
        if (need < 0) return -1;
        sum += need;
    }
    return sum / double(times.size());
}

bool SurfacePipeline::shade(const geometry::Primitive& prim, int nu, int nv, uint64_t id, hider::ShadedGrid& out) {
    const hider::Camera& cam = m_pass.camera;
    const scene::PrimitiveRecord& rec = prim.record();
    const scene::Attributes& attrs = *rec.attributes;
    if (!takesPart(attrs)) return false;

    Mat4 c = cameraFromObject(prim);
    const Mat4 objectFromCamera = c.inverse();
    const geometry::ViewContext view = geometry::ViewContext::ofCamera(objectFromCamera, !cam.perspective);
    geometry::Grid g = prim.diceInView(nu, nv, view);
    // A family may lay its grid out the other way round (Curves: the
    // decision's nu runs along the curve, the grid's v does); the grid's
    // own counts describe it from here on, its shapes are asked as it was.
    const int askedNu = nu, askedNv = nv;
    nu = g.nu;
    nv = g.nv;

    // Motion blur: the piece's object-space positions at each placement
    // time (its shapes interpolated linearly between their times), and the
    // grid shaded once with those at the shutter's opening.
    thread_local std::vector<float> times;
    placementTimes(prim, times);
    const size_t keys = times.size();
    const int n = (nu + 1) * (nv + 1);
    thread_local std::vector<std::vector<Vec3>> shapes;
    thread_local std::vector<Vec3> objectAt;  // keys x n object-space positions
    if (keys > 1) {
        const int shapeCount = prim.shapeCount();
        shapes.resize(size_t(shapeCount));
        shapes[0] = g.P;
        for (int k = 1; k < shapeCount; ++k) prim.diceShape(k, askedNu, askedNv, view, shapes[size_t(k)]);
        objectAt.resize(keys * size_t(n));
        for (size_t k = 0; k < keys; ++k) {
            Vec3* dst = &objectAt[k * size_t(n)];
            if (shapeCount == 1 || rec.shapeTimes.size() != size_t(shapeCount)) {
                std::copy(g.P.begin(), g.P.end(), dst);
                continue;
            }
            const std::vector<float>& st = rec.shapeTimes;
            const float t = std::clamp(times[k], st.front(), st.back());
            size_t a = size_t(std::upper_bound(st.begin(), st.end(), t) - st.begin());
            a = a == 0 ? 0 : std::min(a - 1, st.size() - 2);
            const float span = st[a + 1] - st[a];
            const float f = span > 0 ? std::clamp((t - st[a]) / span, 0.0f, 1.0f) : 0.0f;
            const std::vector<Vec3>&p0 = shapes[a], &p1 = shapes[a + 1];
            for (int i = 0; i < n; ++i) dst[i] = p0[size_t(i)] + (p1[size_t(i)] - p0[size_t(i)]) * f;
        }
        std::copy(objectAt.begin(), objectAt.begin() + n, g.P.begin());
    }
    g.transform(c, objectFromCamera);
    // The family's own normals are outward; an inside-out primitive's point
    // in. User-supplied normals are used as given.
    if (g.ownNormals && attrs.insideOut)
        for (Vec3& nrm : g.N) nrm = -nrm;
    // A normal transforms by the inverse transpose, which divides
    // dPdu x dPdv by the transform's determinant: scaled back, it is the
    // cross product in "current" space, as long as the shading grid's Ng.
    if (g.derivativeNormals) {
        const float scale = std::abs(c.det3());
        for (Vec3& nrm : g.N) nrm = nrm * scale;
    }

    const PreparedAttributes& pa = m_frame.prepared(attrs);
    const bool flip = normalsFlip(attrs, c);
    // A depth pass needs only positions; it runs the shading system just for
    // displacement.
    const std::vector<Vec3>* positions = &g.P;
    shading::ShadingGrid& sg = m_grids.local();
    if (!m_pass.depthOnly || pa.displacement) {
        GridState state{&m_frame, &m_pass, &rec, c};
        sg.resize(nu + 1, nv + 1);
        sg.flipNormals = flip;  // before bind(), which makes Ng
        sg.nearClip = cam.nearClip;  // depth() is 0 at the near clipping plane, 1 at the far
        sg.farClip = cam.farClip;
        sg.time = m_frame.shutterOpen;  // grids are shaded at the shutter's opening
        sg.dtime = m_frame.shutterClose - m_frame.shutterOpen;
        sg.bind(g, attrs.color, attrs.opacity, cam.perspective);
        sg.dPdtime.clear();
        if (keys > 1 && sg.dtime > 0) {
            // dPdtime: from the opening to the close, the undisplaced surface.
            const Mat4 atClose = cameraFromObjectAt(rec, times.back());
            const Vec3* closed = &objectAt[(keys - 1) * size_t(n)];
            sg.dPdtime.resize(size_t(n));
            for (int i = 0; i < n; ++i)
                sg.dPdtime[size_t(i)] = (atClose.point(closed[i]) - g.P[size_t(i)]) / sg.dtime;
        }
        // The path shadow() follows through a map of moving casters: the
        // undisplaced surface at every placement time, the camera held at
        // the opening (a piece only the camera moves past has none, and a
        // depth pass, which runs no light, needs none).
        sg.pathTimes.clear();
        sg.pathOffsets.clear();
        if (keys > 1 && sg.dtime > 0 && rec.moving() && !m_pass.depthOnly) {
            sg.pathTimes.resize(keys);
            sg.pathOffsets.resize(keys * size_t(n));
            for (size_t k = 0; k < keys; ++k) {
                sg.pathTimes[k] = (times[k] - m_frame.shutterOpen) / sg.dtime;
                const Mat4 currentFromObject =
                    cam.cameraFromWorld * (rec.worldFromObjectMotion ? rec.worldFromObjectMotion->at(times[k]) : rec.worldFromObject);
                const Vec3* at = &objectAt[k * size_t(n)];
                for (int i = 0; i < n; ++i)
                    sg.pathOffsets[k * size_t(n) + size_t(i)] = currentFromObject.point(at[i]) - g.P[size_t(i)];
            }
        }
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
        // The thread's CPU clock (a preempted grid is not charged for the
        // wait), read for a sample of the grids: 12% of a frame of
        // 5-micropolygon subdivision grids when every grid was timed.
        thread_local uint64_t shadedGrids = 0;
        const SampledCallTime shadingTime(shadedGrids);
        m_frame.shading->shade(sg, request, m_services);
        m_frame.shadingNanoseconds += shadingTime.nanoseconds();
        positions = &sg.P;
        if (pa.displacement) warnPastDisplacementBound(rec, c, g.P, sg.P, n);
    }
    const std::vector<Vec3>& P = *positions;

    // Camera-space positions at every placement time: key 0 is the shaded
    // grid; later keys move the surface, and carry its displacement along
    // (turned as the piece turns).
    thread_local std::vector<Vec3> cameraAt;
    const std::vector<Vec3>* keyed = &P;
    if (keys > 1) {
        cameraAt.resize(keys * size_t(n));
        std::copy(P.begin(), P.begin() + n, cameraAt.begin());
        for (size_t k = 1; k < keys; ++k) {
            const Mat4 ck = cameraFromObjectAt(rec, times[k]);
            const Mat4 turn = ck * objectFromCamera;  // camera at the opening -> camera at time k
            const Vec3* src = &objectAt[k * size_t(n)];
            Vec3* dst = &cameraAt[k * size_t(n)];
            for (int i = 0; i < n; ++i) dst[i] = ck.point(src[i]) + turn.vector(P[size_t(i)] - g.P[size_t(i)]);
        }
        keyed = &cameraAt;
    }

    out.nu = nu;
    out.nv = nv;
    out.id = id;
    out.matte = attrs.matte;
    out.discs = g.discs;
    out.P.resize(size_t(n) * keys);
    out.keyTimes.clear();
    if (keys > 1) {
        const float span = m_frame.shutterClose - m_frame.shutterOpen;
        for (float t : times) out.keyTimes.push_back(std::clamp((t - m_frame.shutterOpen) / span, 0.0f, 1.0f));
        out.keyTimes.front() = 0.0f;
        out.keyTimes.back() = 1.0f;
    }
    out.bound = Bound3();
    bool anyInFront = false;
    for (size_t i = 0; i < size_t(n) * keys; ++i) {
        const Vec3& p = (*keyed)[i];
        if (cam.perspective && p.z < m_eyeZ) {
            // Displaced (or moved) behind the eye: keep it out of the image.
            out.P[i] = {0, 0, -kInfinity};
            continue;
        }
        out.P[i] = cam.rasterOf(p);
        out.bound.extend(out.P[i]);
        anyInFront = true;
    }
    if (!anyInFront) return false;
    if (keys > 1 || m_pass.lensRadius > 0) noteBlur(out);

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
    // A CSG leaf's surfaces are never culled by facing: the ray leaving a
    // solid through its far side is what makes the cut surfaces of a
    // difference visible.
    out.csgLeaf = rec.solid;
    out.dissolveFrom = pa.dissolveFrom;
    out.dissolveBelow = pa.dissolveBelow;
    out.leaving.clear();
    if (rec.solid >= 0)
        markLeaving(P, flip, out);
    else if (attrs.sides == 1 && m_pass.cull != Pass::Cull::None && !cullFacing(*keyed, keys, flip, out))
        return false;

    out.ownSecondLayer = m_pass.depthOnly && m_pass.openSurfacesAreOwnSecondLayer && attrs.sides == 2;
    if (m_pass.depthOnly) {
        out.Ci.clear();
        out.Oi.clear();
        out.aovFloats = 0;
        return true;
    }
    out.Ci.assign(sg.Ci.begin(), sg.Ci.begin() + n);
    // An opaque grid (every Oi at least 1 in each channel, which the hider
    // samples as exactly opaque without reading Oi) keeps no Oi: a third of
    // what each grid waiting for its last bucket holds.
    const bool opaque = std::all_of(sg.Oi.begin(), sg.Oi.begin() + n,
                                    [](const Color& o) { return o.x >= 1.0f && o.y >= 1.0f && o.z >= 1.0f; });
    if (opaque)
        out.Oi.clear();
    else
        out.Oi.assign(sg.Oi.begin(), sg.Oi.begin() + n);
    fillAovs(sg, out);
    return true;
}

void SurfacePipeline::warnPastDisplacementBound(const scene::PrimitiveRecord& rec, const Mat4& cameraFromObject,
                                                const std::vector<Vec3>& before, const std::vector<Vec3>& after,
                                                int n) const {
    // Pieces are placed in buckets, and culled, by their bounds grown by the
    // displacement bound before they are shaded; a surface displaced past
    // it loses the pieces whose bucket was already done (the RenderMan
    // Companion's torn figure 17.13). PRMan warns too. Once per
    // Displacement request, at it.
    const scene::Attributes& attrs = *rec.attributes;
    const float allowed = displacementAllowance(attrs, cameraFromObject);
    float moved = 0, size = 0;
    for (int i = 0; i < n; ++i) {
        moved = std::max(moved, length(after[size_t(i)] - before[size_t(i)]));
        size = std::max(size, length(before[size_t(i)]));
    }
    if (moved <= allowed * 1.01f + 1e-5f * size) return;
    const scene::ShaderRecord& d = *attrs.displacement;
    m_diag.warningOnce(fmt::format("displacementbound:{}", static_cast<const void*>(&d)), d.loc,
                       "Displacement \"{}\" moves {} {:.3g} camera units but its Attribute \"displacementbound\" "
                       "\"sphere\" allows {:.3g}: pieces displaced past their bound may be missing from the picture",
                       d.name, rec.type, moved, allowed);
}

void SurfacePipeline::noteBlur(const hider::ShadedGrid& out) const {
    // The grid's raster bound at the opening, and over every key with the
    // circle of confusion: what blur costs the hider in area to search.
    const int n = (out.nu + 1) * (out.nv + 1);
    Bound3 still, blurred;
    for (int i = 0; i < n; ++i)
        if (out.P[size_t(i)].z > -kInfinity) still.extend(out.P[size_t(i)]);
    for (const Vec3& p : out.P)
        if (p.z > -kInfinity) {
            const float r = confusionRadius(p.z);
            blurred.extend(Vec3(p.x - r, p.y - r, p.z));
            blurred.extend(Vec3(p.x + r, p.y + r, p.z));
        }
    auto area = [](const Bound3& b) {
        return b.empty() ? 0.0 : double(b.max.x - b.min.x + 1) * double(b.max.y - b.min.y + 1);
    };
    m_frame.blurredGrids.fetch_add(1, std::memory_order_relaxed);
    m_frame.stillBoundPixels.fetch_add(uint64_t(std::min(area(still), 1e15)), std::memory_order_relaxed);
    m_frame.blurredBoundPixels.fetch_add(uint64_t(std::min(area(blurred), 1e15)), std::memory_order_relaxed);
}

void SurfacePipeline::markLeaving(const std::vector<Vec3>& P, bool flip, hider::ShadedGrid& out) const {
    // As cullFacing() at the shutter's opening: a micropolygon whose outward
    // normal faces away from the eye is where the ray leaves the solid.
    const int nu = out.nu, nv = out.nv, nu1 = nu + 1;
    const bool perspective = m_pass.camera.perspective;
    out.leaving.assign(size_t(nu) * size_t(nv), 0);
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const Vec3& a = P[size_t(j * nu1 + i)];
            const Vec3& d = P[size_t((j + 1) * nu1 + i + 1)];
            Vec3 n = cross(d - a, P[size_t((j + 1) * nu1 + i)] - P[size_t(j * nu1 + i + 1)]);
            Vec3 centre = (a + d) * 0.5f;
            float toward = perspective ? dot(n, centre) : n.z;  // > 0: faces away (unflipped)
            out.leaving[size_t(j * nu + i)] = (flip ? toward < 0 : toward > 0) ? 1 : 0;
        }
}

bool SurfacePipeline::cullFacing(const std::vector<Vec3>& keyed, size_t keys, bool flip,
                                 hider::ShadedGrid& out) const {
    // A micropolygon faces the eye when its outward normal points at it:
    // dPdu x dPdv in camera space, negated when normalsFlip() says so. A
    // moving one culled at some keys and not at others is kept at the
    // sample times it faces the way it should (the hider tells by its
    // winding then, MicroGrid::Facing): a card turning its back during the
    // shutter shows for the part it faces the eye.
    using Facing = hider::MicroGrid::Facing;
    const int nu = out.nu, nv = out.nv, nu1 = nu + 1;
    const size_t verts = size_t(nu1) * size_t(nv + 1);
    const bool perspective = m_pass.camera.perspective;
    const bool dropFront = m_pass.cull == Pass::Cull::Front;
    out.culled.assign(size_t(nu) * size_t(nv), Facing::kCulled);
    thread_local std::vector<uint8_t> keptAtOpening, droppedSomewhere;
    keptAtOpening.assign(out.culled.size(), 0);
    droppedSomewhere.assign(out.culled.size(), 0);
    bool anyKept = false;
    for (size_t k = 0; k < keys; ++k) {
        const Vec3* P = keyed.data() + k * verts;
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
                const size_t m = size_t(j * nu + i);
                if (!drop) out.culled[m] = Facing::kKept;
                if (k == 0) keptAtOpening[m] = !drop;
                droppedSomewhere[m] |= drop;
                anyKept |= !drop;
            }
    }
    if (keys > 1)
        for (size_t m = 0; m < out.culled.size(); ++m)
            if (out.culled[m] == Facing::kKept && droppedSomewhere[m])
                out.culled[m] = keptAtOpening[m] ? Facing::kKeepAsOpening : Facing::kKeepUnlikeOpening;
    return anyKept;
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
