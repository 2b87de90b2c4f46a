#include "render/light_view.h"

#include "shading/slc.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace umbra::render {

namespace {

/// A point parameter of the light record, in world space, if given.
std::optional<Vec3> pointParam(const scene::LightRecord& light, const char* name) {
    const ri::Param* p = light.shader.params.find(name);
    if (!p || p->floats.size() < 3) return std::nullopt;
    return light.shader.worldFromShader.point({p->floats[0], p->floats[1], p->floats[2]});
}

/// A float parameter: the record's value, else the shader's constant
/// default, else `fallback`.
float floatParam(const scene::LightRecord& light, const shading::Shader* shader, const char* name, float fallback) {
    if (const ri::Param* p = light.shader.params.find(name); p && !p->floats.empty()) return p->floats[0];
    if (shader)
        if (const auto* info = shader->param(name); info && info->constantDefault && !info->defaultFloats.empty())
            return info->defaultFloats[0];
    return fallback;
}

bool contains(const std::string& s, const char* part) { return s.find(part) != std::string::npos; }

}  // namespace

LightGeometry lightGeometry(const scene::LightRecord& light, const shading::Shader* shader) {
    LightGeometry g;
    const std::string& name = light.shader.name;
    bool hasCone = light.shader.params.find("coneangle") || (shader && shader->param("coneangle"));
    if (shader && shader->code().isSolarLight)
        g.shape = LightShape::Distant;  // solar(): whatever the user named it
    else if (contains(name, "spot") || hasCone)
        g.shape = LightShape::Spot;
    else if (contains(name, "distant") || contains(name, "solar"))
        g.shape = LightShape::Distant;
    else if (contains(name, "point") || (shader && !shader->code().isAmbientLight))
        g.shape = LightShape::Point;  // illuminate() from a position without a cone
    // RenderMan's defaults: from the shader-space origin along its +z axis.
    g.from = pointParam(light, "from").value_or(light.shader.worldFromShader.point({0, 0, 0}));
    g.to = pointParam(light, "to").value_or(light.shader.worldFromShader.point({0, 0, 1}));
    g.coneAngle = floatParam(light, shader, "coneangle", radians(30));
    g.coneDelta = floatParam(light, shader, "conedeltaangle", radians(5));
    return g;
}

Mat4 lookAt(const Vec3& from, const Vec3& to) {
    Vec3 z = normalize(to - from);
    Vec3 up = std::abs(z.y) > 0.999f ? Vec3(0, 0, 1) : Vec3(0, 1, 0);
    Vec3 x = normalize(cross(up, z));  // left-handed: x = up × z gives +x right
    Vec3 y = cross(z, x);
    Mat4 r;
    const Vec3 axes[3] = {x, y, z};
    for (int i = 0; i < 3; ++i) {
        r.m[i][0] = axes[i].x;
        r.m[i][1] = axes[i].y;
        r.m[i][2] = axes[i].z;
    }
    return r * Mat4::translate(-from);
}

std::optional<Pass> lightPass(const LightGeometry& light, const std::vector<geometry::PrimitivePtr>& prims,
                              int resolution, const std::string& name, Diagnostics& diag, const FileLoc& loc) {
    Pass pass;
    pass.name = name;
    pass.depthOnly = true;
    hider::Camera& cam = pass.camera;
    cam.xResolution = cam.yResolution = std::max(1, resolution);
    if (length(light.to - light.from) <= 0) {
        diag.warning(loc, "LightSource: \"from\" and \"to\" coincide; no depth map can be rendered for it");
        return std::nullopt;
    }
    if (light.shape == LightShape::Spot) {
        cam.perspective = true;
        // The cone fills the map, with a little room for filter regions at its edge.
        float half = clamp(light.coneAngle * 1.05f, radians(0.5f), radians(85.0f));
        cam.tanHalfFov = std::tan(half);
        pass.discOnly = true;
        cam.cameraFromWorld = lookAt(light.from, light.to);
        cam.nearClip = 1e-3f;
        cam.farClip = 1e30f;
    } else if (light.shape == LightShape::Distant) {
        // Orthographic along the light, fitted to everything that casts.
        Mat4 rotation = lookAt({0, 0, 0}, light.to - light.from);
        Bound3 b;
        for (const auto& p : prims) {
            if (!p->attributes().castsShadows) continue;
            const scene::PrimitiveRecord& rec = p->record();
            b.extend(transformBound(rotation * rec.worldFromObject, p->bound()));
            // A moving caster: everywhere its keys take it, arcs included.
            if (!rec.worldFromObjectMotion) continue;
            const std::vector<float> keys = rec.worldFromObjectMotion->keyTimes();
            for (size_t k = 0; k < keys.size(); ++k)
                for (int i = 0; i < (k + 1 < keys.size() ? 8 : 1); ++i) {
                    const float t = k + 1 < keys.size() ? keys[k] + (keys[k + 1] - keys[k]) * float(i) / 8 : keys[k];
                    b.extend(transformBound(rotation * rec.worldFromObjectMotion->at(t), p->bound()));
                }
        }
        if (b.empty()) return std::nullopt;
        Vec3 c = (b.min + b.max) * 0.5f;
        float half = 0.51f * std::max(b.max.x - b.min.x, b.max.y - b.min.y) + 1e-4f;
        float depth = b.max.z - b.min.z;
        cam.perspective = false;
        cam.cameraFromWorld = Mat4::translate({-c.x, -c.y, -(b.min.z - 0.01f * depth - 1e-3f)}) * rotation;
        cam.screenWindow[0] = -half;
        cam.screenWindow[1] = half;
        cam.screenWindow[2] = -half;
        cam.screenWindow[3] = half;
        cam.nearClip = 0;
        cam.farClip = 1e30f;
    } else {
        diag.warningOnce("auto-map " + name, loc,
                         "LightSource: automatic shadow maps are made for spot and distant lights; this light "
                         "({}) gets none and is unshadowed",
                         light.shape == LightShape::Point ? "a point light, which needs a cube map" : "of unknown shape");
        return std::nullopt;
    }
    cam.finish();
    return pass;
}

std::array<Pass, 6> cubeFacePasses(const LightGeometry& light, int resolution, const std::string& name) {
    static const Vec3 kAxes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    static const char* kFaces[6] = {"+x", "-x", "+y", "-y", "+z", "-z"};
    std::array<Pass, 6> passes;
    for (int f = 0; f < 6; ++f) {
        Pass& pass = passes[size_t(f)];
        pass.name = name + kFaces[f];
        pass.depthOnly = true;
        hider::Camera& cam = pass.camera;
        cam.xResolution = cam.yResolution = std::max(1, resolution);
        cam.perspective = true;
        // A little over 90 degrees, so filter regions at a face's edge stay
        // inside the face the lookup picks.
        cam.tanHalfFov = 1.02f;
        cam.cameraFromWorld = lookAt(light.from, light.from + kAxes[f]);
        cam.nearClip = 1e-3f;
        cam.farClip = 1e30f;
        cam.finish();
    }
    return passes;
}

namespace {

/// The image's header from the pass; its depths from the film's layers,
/// the nearest depths read from the film's plane or, `inPlace`, from the
/// image itself (the plane taken whole): each texel is read before it is
/// written.
void fillDepthImage(DepthImage& image, const film::Film& film, bool inPlace, const Pass& pass, DepthFilter filter,
                    float dualOffset) {
    const hider::Camera& camera = pass.camera;
    const bool frontCulled = pass.cull == Pass::Cull::Front;
    image.lightFromWorld = camera.cameraFromWorld;
    image.ndcFromWorld = camera.ndcFromScreen() * camera.screenFromCamera() * camera.cameraFromWorld;
    image.projection = camera.perspective ? Projection::Perspective : Projection::Orthographic;
    image.filter = filter;
    image.dualOffset = dualOffset;
    image.timeTile = pass.timeTile;
    // Row by row, with the filter's rule chosen once (a switch per pixel
    // cost more than the copy).
    // Only the texels the pass wrote (the image's window, inside the film).
    const int wx0 = std::max(film.x0(), image.columnBegin()), wx1 = std::min(film.x1(), image.columnEnd());
    const int wy0 = std::max(film.y0(), image.rowBegin()), wy1 = std::min(film.y1(), image.rowEnd());
    auto convert = [&](auto layer) {
        const bool pair = film.hasDepthPair();
        for (int y = wy0; y < wy1; ++y) {
            const float* z1row = inPlace ? &image.z[size_t(y) * size_t(image.width) + size_t(wx0)]
                                         : film.zRow(y) + (wx0 - film.x0());
            const float* z2row = pair ? film.z2Row(y) + (wx0 - film.x0()) : nullptr;
            float* out = &image.z[size_t(y) * size_t(image.width) + size_t(wx0)];
            const float v = 2.0f * (float(y) + 0.5f) / float(image.height) - 1.0f;
            for (int x = wx0, i = 0; x < wx1; ++x, ++i) {
                const float z1 = z1row[i];
                float z = std::isfinite(z1) ? layer(z1, z2row ? z2row[i] : kInfinity) : kInfinity;
                if (pass.discOnly) {
                    const float u = 2.0f * (float(x) + 0.5f) / float(image.width) - 1.0f;
                    if (u * u + v * v > 1.0f) z = kInfinity;
                }
                out[i] = z;
            }
        }
    };
    switch (filter) {
    case DepthFilter::Min:
    case DepthFilter::Max:
    case DepthFilter::Average:
        if (inPlace && !pass.discOnly) return;  // the image holds them already
        convert([](float z1, float) { return z1; });  // the hider already reduced the pixel's samples
        break;
    case DepthFilter::Second: convert([&](float z1, float z2) { return frontCulled ? z1 : z2; }); break;  // single layer: +infinity
    case DepthFilter::Midpoint:
        // Single layer: the dual rule keeps the midpoint finite.
        convert([&](float z1, float z2) { return std::isfinite(z2) ? 0.5f * (z1 + z2) : z1 + dualOffset; });
        break;
    case DepthFilter::Dual:
        convert([&](float z1, float z2) {
            return std::isfinite(z2) ? z1 + std::min(0.5f * (z2 - z1), dualOffset) : z1 + dualOffset;
        });
        break;
    }
}

}  // namespace

DepthImage depthImageOf(const film::Film& film, const Pass& pass, DepthFilter filter, float dualOffset) {
    DepthImage image(film.xResolution(), film.yResolution());
    fillDepthImage(image, film, false, pass, filter, dualOffset);
    return image;
}

DepthImage depthImageOf(film::Film&& film, const Pass& pass, DepthFilter filter, float dualOffset) {
    const film::Film::DepthWindow written = film.settleDepth();
    FloatPlane plane = film.takeDepth();
    const bool inPlace = !plane.empty();
    DepthImage image = inPlace ? DepthImage() : DepthImage(film.xResolution(), film.yResolution());
    if (inPlace) {
        image.width = film.xResolution();
        image.height = film.yResolution();
        image.z = std::move(plane);
    }
    image.writtenX0 = written.x0, image.writtenY0 = written.y0;
    image.writtenX1 = written.x1, image.writtenY1 = written.y1;
    fillDepthImage(image, film, inPlace, pass, filter, dualOffset);
    return image;
}

}  // namespace umbra::render
