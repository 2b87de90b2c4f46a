#include "umbra/geometry/primvars.h"

#include <fmt/format.h>

#include <algorithm>

namespace umbra::geometry {

namespace {

size_t expectedCount(const ClassCounts& c, ri::StorageClass s, const char** what) {
    switch (s) {
    case ri::StorageClass::Constant: *what = "one for the primitive"; return 1;
    case ri::StorageClass::Uniform: *what = c.uniformWhat; return c.uniform;
    case ri::StorageClass::Varying: *what = c.varyingWhat; return c.varying;
    case ri::StorageClass::Vertex: *what = c.vertexWhat; return c.vertex;
    case ri::StorageClass::FaceVarying:
    case ri::StorageClass::FaceVertex: *what = c.faceVaryingWhat; return c.faceVarying;
    }
    *what = "";
    return 1;
}

// Checks a parameter's value count against its class; false (with an error)
// when it does not fit.
bool checkCount(const scene::PrimitiveRecord& rec, const ri::Param& p, ri::StorageClass storage,
                const ClassCounts& counts, Diagnostics& diag) {
    const int elem = p.decl.elementSize();
    if (elem <= 0) return false;
    if (p.floats.size() % size_t(elem) != 0) {
        diag.error(rec.loc, "{}: \"{}\" has {} floats, not a multiple of {} ({})", rec.type, p.decl.name,
                   p.floats.size(), elem, p.decl.str());
        return false;
    }
    const char* what = "";
    size_t want = expectedCount(counts, storage, &what);
    size_t have = p.floats.size() / size_t(elem);
    if (have != want) {
        diag.error(rec.loc, "{}: \"{}\" has {} values, expected {} ({})", rec.type, p.decl.name, have, want, what);
        return false;
    }
    return true;
}

/// A constant or uniform string variable (an exporter's per-object texture
/// name, say) becomes indices into a table of its values, which ride on
/// grids as floats and bind to the shader's string parameter of that name.
void addStringVar(const scene::PrimitiveRecord& rec, const ri::Param& p, const ClassCounts& counts,
                  Diagnostics& diag, SurfaceData& sd) {
    const std::string& name = p.decl.name;
    rec.params.find(name);  // mark used
    if (p.decl.elementSize() != 1) {
        diag.warningOnce("string-primvar-array:" + name, rec.loc,
                         "{}: string array \"{}\" cannot be a primitive variable; ignored", rec.type, name);
        return;
    }
    if (p.decl.storage != ri::StorageClass::Constant && p.decl.storage != ri::StorageClass::Uniform) {
        diag.warningOnce("string-primvar-class:" + name, rec.loc,
                         "{}: string \"{}\" is {}: a string primitive variable is constant or uniform; ignored",
                         rec.type, name, p.decl.str());
        return;
    }
    const char* what = "";
    const size_t want = expectedCount(counts, p.decl.storage, &what);
    if (p.strings.size() != want) {
        diag.error(rec.loc, "{}: \"{}\" has {} values, expected {} ({})", rec.type, name, p.strings.size(), want, what);
        return;
    }
    const std::vector<std::string>& table = sd.stringTables.emplace_back(p.strings);
    std::vector<float>& indices = sd.stringIndices.emplace_back(table.size());
    for (size_t k = 0; k < indices.size(); ++k) indices[k] = float(k);
    PrimVar v;
    v.name = name;
    v.type = ri::ParamType::String;
    v.storage = p.decl.storage;
    v.data = indices.data();
    v.count = indices.size();
    v.strings = &table;
    sd.vars.push_back(std::move(v));
}

}  // namespace

std::shared_ptr<const SurfaceData> readSurfaceData(const scene::PrimitiveRecord& rec, const ClassCounts& counts,
                                                   bool posRequired, Diagnostics& diag, bool allowPz, int pzNu,
                                                   int pzNv, bool pzPeriodicU, bool pzPeriodicV) {
    auto sd = std::make_shared<SurfaceData>();
    if (rec.attributes) {
        sd->defaultCs = rec.attributes->color;
        sd->defaultOs = rec.attributes->opacity;
        static const char* const kParametric[] = {"Sphere", "Cone", "Cylinder", "Hyperboloid", "Paraboloid",
                                                  "Disk", "Torus", "Patch", "PatchMesh", "NuPatch"};
        for (const char* t : kParametric)
            if (rec.type == t) std::copy(rec.attributes->textureCoordinates, rec.attributes->textureCoordinates + 8, sd->cornerST);
    }
    const ri::Param* P = rec.params.find("P");
    const ri::Param* Pw = P ? nullptr : rec.params.find("Pw");
    const ri::Param* Pz = (P || Pw || !allowPz) ? nullptr : rec.params.find("Pz");
    const ri::Param* posParam = P ? P : (Pw ? Pw : Pz);
    if (!posParam) {
        if (posRequired) {
            diag.error(rec.loc, "{}: missing \"P\"{} (positions are required)", rec.type,
                       allowPz ? ", \"Pw\" or \"Pz\"" : " or \"Pw\"");
            return nullptr;
        }
    } else {
        const int want = posParam == P ? 3 : (posParam == Pw ? 4 : 1);
        if (posParam->decl.elementSize() != want || !ri::isFloatType(posParam->decl.type)) {
            diag.error(rec.loc, "{}: \"{}\" must be declared with {} floats per value, got \"{}\"", rec.type,
                       posParam->decl.name, want, posParam->decl.str());
            return nullptr;
        }
        if (!checkCount(rec, *posParam, ri::StorageClass::Vertex, counts, diag)) return nullptr;
        sd->posCount = counts.vertex;
        if (posParam == Pz) {
            // RI spec: Pz gives heights over the unit square, x and y following
            // the control-point grid.
            sd->ownedPos.resize(size_t(pzNu) * size_t(pzNv) * 3);
            const float du = pzPeriodicU ? 1.0f / float(pzNu) : 1.0f / float(std::max(pzNu - 1, 1));
            const float dv = pzPeriodicV ? 1.0f / float(pzNv) : 1.0f / float(std::max(pzNv - 1, 1));
            for (int j = 0; j < pzNv; ++j)
                for (int i = 0; i < pzNu; ++i) {
                    float* o = &sd->ownedPos[(size_t(j) * size_t(pzNu) + size_t(i)) * 3];
                    o[0] = float(i) * du;
                    o[1] = float(j) * dv;
                    o[2] = Pz->floats[size_t(j) * size_t(pzNu) + size_t(i)];
                }
            sd->pos = sd->ownedPos.data();
            sd->posDim = 3;
        } else {
            sd->pos = posParam->floats.data();
            sd->posDim = want;
        }
    }

    const bool hasN = rec.params.find("N") != nullptr;
    for (const ri::Param& p : rec.params.params()) {
        const std::string& name = p.decl.name;
        if (name == "P" || name == "Pw" || name == "Pz") continue;
        if (p.decl.type == ri::ParamType::String) {
            addStringVar(rec, p, counts, diag, *sd);
            continue;
        }
        if (!ri::isFloatType(p.decl.type)) continue;  // integers cannot ride on a grid
        if (name == "Np" && hasN) continue;
        rec.params.find(name);  // mark used
        if (!checkCount(rec, p, p.decl.storage, counts, diag)) continue;
        PrimVar v;
        v.name = name;
        v.type = p.decl.type;
        v.storage = p.decl.storage;
        v.components = p.decl.elementSize();
        v.stride = v.components;
        v.data = p.floats.data();
        v.count = p.floats.size() / size_t(v.components);
        if (name == "N" || name == "Np") {
            if (v.components != 3) {
                diag.error(rec.loc, "{}: \"{}\" must have 3 floats per value, got \"{}\"", rec.type, name, p.decl.str());
                continue;
            }
            v.name = std::string(1, 'N');
            v.isNormal = true;
        } else if (name == "st") {
            if (v.components != 2) {
                diag.error(rec.loc, "{}: \"st\" must have 2 floats per value, got \"{}\"", rec.type, p.decl.str());
                continue;
            }
            auto half = [&](std::string n, int offset) {
                PrimVar h;
                h.name = std::move(n);
                h.storage = v.storage;
                h.components = 1;
                h.stride = 2;
                h.offset = offset;
                h.data = v.data;
                h.count = v.count;
                return h;
            };
            const PrimVar s = half(std::string(1, 's'), 0), t = half(std::string(1, 't'), 1);
            // Explicit "s"/"t" win over "st".
            if (!sd->hasS) { sd->vars.push_back(s); sd->hasS = true; }
            if (!sd->hasT) { sd->vars.push_back(t); sd->hasT = true; }
            continue;
        } else if (name == "s" || name == "t") {
            bool& has = name == "s" ? sd->hasS : sd->hasT;
            if (has) {
                for (auto& e : sd->vars)
                    if (e.name == name) e = v;
                continue;
            }
            has = true;
        } else if (name == "Cs") {
            sd->hasCs = true;
        } else if (name == "Os") {
            sd->hasOs = true;
        }
        sd->vars.push_back(v);
    }
    return sd;
}

void initGrid(Grid& g, int nu, int nv, const ParamRange& r, const ParamMap& map, std::vector<float>& a,
              std::vector<float>& b) {
    g.nu = nu;
    g.nv = nv;
    const size_t n = size_t(nu + 1) * size_t(nv + 1);
    g.P.resize(n);
    g.u.resize(n);
    g.v.resize(n);
    a.resize(size_t(nu) + 1);
    b.resize(size_t(nv) + 1);
    const float su = (r.u1 - r.u0) / float(nu), sv = (r.v1 - r.v0) / float(nv);
    for (int i = 0; i <= nu; ++i) a[size_t(i)] = i == nu ? r.u1 : r.u0 + su * float(i);
    for (int j = 0; j <= nv; ++j) b[size_t(j)] = j == nv ? r.v1 : r.v0 + sv * float(j);
    g.du = su * map.uScale;
    g.dv = sv * map.vScale;
    size_t k = 0;
    for (int j = 0; j <= nv; ++j) {
        const float gv = map.vOffset + map.vScale * b[size_t(j)];
        for (int i = 0; i <= nu; ++i, ++k) {
            g.u[k] = map.uOffset + map.uScale * a[size_t(i)];
            g.v[k] = gv;
        }
    }
}

bool setDerivativeNormals(Grid& g, const float* H, const float* Ha, const float* Hb, int posDim, const ParamMap& map) {
    const size_t n = g.P.size();
    g.N.resize(n);
    const float su = map.uScale != 0 ? 1.0f / map.uScale : 0.0f, sv = map.vScale != 0 ? 1.0f / map.vScale : 0.0f;
    for (size_t k = 0; k < n; ++k) {
        const float* h = H + 4 * k;
        const float* ha = Ha + 4 * k;
        const float* hb = Hb + 4 * k;
        Vec3 pa(ha[0], ha[1], ha[2]), pb(hb[0], hb[1], hb[2]);
        if (posDim == 4) {
            // P = H / w: P' = (H' w - H w') / w^2, the common 1/w^2 kept
            // as a scale of the cross product (1/w^4).
            const Vec3 xyz(h[0], h[1], h[2]);
            pa = pa * h[3] - xyz * ha[3];
            pb = pb * h[3] - xyz * hb[3];
            const float w2 = h[3] * h[3];
            pa = pa / w2, pb = pb / w2;
        }
        pa = pa * su, pb = pb * sv;
        const Vec3 c = cross(pa, pb);
        const float len = length(c);
        if (!(len > 1e-6f * length(pa) * length(pb)) || !(len < kInfinity)) {
            g.N.clear();
            return false;
        }
        g.N[k] = c;
    }
    g.ownNormals = true;
    g.derivativeNormals = true;
    return true;
}

GridVar& addGridVar(Grid& g, const PrimVar& v, bool perVertex) {
    GridVar& gv = g.vars.emplace_back();
    gv.name = v.name;
    gv.type = v.type;
    gv.components = v.components;
    gv.perVertex = perVertex;
    gv.strings = v.strings;
    gv.data.resize(perVertex ? size_t(g.vertexCount()) * size_t(v.components) : size_t(v.components));
    return gv;
}

namespace {

// Bilinear interpolation of `comps` floats from four corners onto the grid.
void bilerpFill(const float* c0, const float* c1, const float* c2, const float* c3, int comps,
                const std::vector<float>& a, const std::vector<float>& b, float* out) {
    constexpr int kMax = 64;
    float L[kMax], R[kMax];
    for (int base = 0; base < comps; base += kMax) {
        const int n = std::min(kMax, comps - base);
        float* o = out + base;
        for (float bv : b) {
            for (int k = 0; k < n; ++k) {
                L[k] = c0[base + k] + bv * (c2[base + k] - c0[base + k]);
                R[k] = c1[base + k] + bv * (c3[base + k] - c1[base + k]);
            }
            for (float av : a) {
                for (int k = 0; k < n; ++k) o[k] = L[k] + av * (R[k] - L[k]);
                o += comps;
            }
        }
    }
}

}  // namespace

void interpolateVars(const SurfaceData& sd, const CornerRefs& refs, const std::vector<float>& a,
                     const std::vector<float>& b, bool skipVertex, Grid& g) {
    const size_t n = size_t(g.vertexCount());
    for (const PrimVar& v : sd.vars) {
        const int* corners = nullptr;
        switch (v.storage) {
        case ri::StorageClass::Varying: corners = refs.varying; break;
        case ri::StorageClass::Vertex:
            if (skipVertex) continue;
            corners = refs.vertex;
            break;
        case ri::StorageClass::FaceVarying:
        case ri::StorageClass::FaceVertex: corners = refs.faceVarying; break;
        default: break;
        }
        if (v.isNormal) {
            g.N.resize(n);
            if (corners) {
                bilerpFill(v.at(size_t(corners[0])), v.at(size_t(corners[1])), v.at(size_t(corners[2])),
                           v.at(size_t(corners[3])), 3, a, b, &g.N[0].x);
            } else {
                const float* c = v.at(v.storage == ri::StorageClass::Uniform ? size_t(refs.uniform) : 0);
                std::fill(g.N.begin(), g.N.end(), Vec3(c[0], c[1], c[2]));
            }
            continue;
        }
        if (corners) {
            GridVar& gv = addGridVar(g, v, true);
            if (v.stride == v.components) {
                bilerpFill(v.at(size_t(corners[0])), v.at(size_t(corners[1])), v.at(size_t(corners[2])),
                           v.at(size_t(corners[3])), v.components, a, b, gv.data.data());
            } else {
                float c[4][64];
                for (int q = 0; q < 4; ++q)
                    for (int k = 0; k < v.components && k < 64; ++k) c[q][k] = v.at(size_t(corners[q]))[k];
                bilerpFill(c[0], c[1], c[2], c[3], std::min(v.components, 64), a, b, gv.data.data());
            }
        } else {
            GridVar& gv = addGridVar(g, v, false);
            const float* c = v.at(v.storage == ri::StorageClass::Uniform ? size_t(refs.uniform) : 0);
            std::copy(c, c + v.components, gv.data.begin());
        }
    }
    addDefaultVars(sd, g);
}

void addDefaultVars(const SurfaceData& sd, Grid& g) {
    auto addDefault = [&](const char* name, const std::vector<float>& src) {
        GridVar& gv = g.vars.emplace_back();
        gv.name = name;
        gv.data = src;
    };
    // s and t default to u and v mapped through TextureCoordinates:
    // bilinear in (u, v) between the four corners' values.
    const float* c = sd.cornerST;
    const bool identity = c[0] == 0 && c[1] == 0 && c[2] == 1 && c[3] == 0 && c[4] == 0 && c[5] == 1 && c[6] == 1 &&
                          c[7] == 1;
    auto addMapped = [&](const char* name, int k) {
        GridVar& gv = g.vars.emplace_back();
        gv.name = name;
        gv.data.resize(g.u.size());
        for (size_t i = 0; i < g.u.size(); ++i) {
            const float u = g.u[i], v = g.v[i];
            gv.data[i] = (1 - v) * ((1 - u) * c[k] + u * c[2 + k]) + v * ((1 - u) * c[4 + k] + u * c[6 + k]);
        }
    };
    if (!sd.hasS) {
        if (identity) addDefault("s", g.u);
        else addMapped("s", 0);
    }
    if (!sd.hasT) {
        if (identity) addDefault("t", g.v);
        else addMapped("t", 1);
    }
    auto addColor = [&](const char* name, const Color& c) {
        GridVar& gv = g.vars.emplace_back();
        gv.name = name;
        gv.type = ri::ParamType::Color;
        gv.components = 3;
        gv.perVertex = false;
        gv.data = {c.x, c.y, c.z};
    };
    if (!sd.hasCs) addColor("Cs", sd.defaultCs);
    if (!sd.hasOs) addColor("Os", sd.defaultOs);
}

}  // namespace umbra::geometry
