// Second-depth maps with virtual samples (Wang & Molnar 1994, Figure 10).

#include "shadow_test_util.h"
#include "umbra/util/rng.h"

#include <cmath>

namespace umbra {
namespace {

struct Surface {
    std::vector<Vec3> P, du, dv, N;
    ShadowBatch batch(uint32_t seed, bool normals = true) const {
        ShadowBatch b;
        b.count = int(P.size());
        b.P = P.data();
        b.dPdu_du = du.data();
        b.dPdv_dv = dv.data();
        b.N = normals ? N.data() : nullptr;
        b.seed = seed;
        return b;
    }
};

// Orthographic light, raster = world x, y. A receiver plane z = 50 + 0.3 x
// is stored as the (second) depth at texel centres; over x < 64 an
// occluder's back face at z = 12 is stored instead.
DepthImage slopeImage(DepthFilter filter, bool occluder) {
    DepthImage img(128, 64);
    test::setRasterIsWorld(img);
    img.filter = filter;
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 128; ++x) img.at(x, y) = (occluder && x < 64) ? 12.0f : 50.0f + 0.3f * (float(x) + 0.5f);
    return img;
}

Surface pointsOnSlope(int n, float x0, float x1, uint32_t seed) {
    Surface s;
    Rng rng(seed);
    const Vec3 du(4, 0, 1.2f), dv(0, 4, 0);  // 4-texel micropolygons on the plane
    for (int i = 0; i < n; ++i) {
        float x = x0 + (x1 - x0) * rng.uniform(), y = 8 + 48 * rng.uniform();
        s.P.push_back(Vec3(x, y, 50 + 0.3f * x));
        s.du.push_back(du);
        s.dv.push_back(dv);
        s.N.push_back(normalize(cross(du, dv)) * -1.0f);  // facing the light (-z)
    }
    return s;
}

/// Looked up again without the culling tests, every point of `batch`
/// takes virtual samples and gets what `culled` (the lookup with them) got.
void expectUnculledVirtualSamplesAgree(const ShadowMap& map, const ShadowBatch& batch, ShadowParams params,
                                       const std::vector<float>& culled) {
    params.tileCulling = false;
    std::vector<float> out(size_t(batch.count));
    ShadowStats st;
    map.lookup(batch, params, out.data(), st);
    EXPECT_EQ(out, culled);
    EXPECT_EQ(st.virtualPoints, uint64_t(batch.count));
}

TEST(SecondDepth, VirtualSamplesRemoveSelfShadowingWithoutBias) {
    auto second = test::writeAndOpen(slopeImage(DepthFilter::Second, false), "slope_second.exr");
    auto first = test::writeAndOpen(slopeImage(DepthFilter::Min, false), "slope_min.exr");
    ASSERT_TRUE(second && first);
    Surface pts = pointsOnSlope(500, 10, 118, 4);
    ShadowParams params;
    params.bias = 0;  // no bias needed; one texel of slope is 0.3
    std::vector<float> outSecond(pts.P.size()), outFirst(pts.P.size());
    ShadowStats stSecond, stFirst;
    second->lookup(pts.batch(1), params, outSecond.data(), stSecond);
    first->lookup(pts.batch(1), params, outFirst.data(), stFirst);
    double acne = 0;
    for (size_t i = 0; i < pts.P.size(); ++i) {
        EXPECT_EQ(outSecond[i], 0.0f) << pts.P[i].x;
        acne += outFirst[i];
    }
    // Plain PCF on the same slope shadows itself: about half of the samples
    // lie on texels nearer the light than the point.
    EXPECT_GT(acne / double(pts.P.size()), 0.3);
    // The slope is stored as itself (an open surface, §3.3): points on it
    // are lit from the stored planes of the blocks, or by virtual samples
    // where a region reaches past them (the map's edge).
    EXPECT_GT(stSecond.storedPlaneLit, pts.P.size() / 2);
    EXPECT_EQ(stSecond.storedPlaneLit + stSecond.virtualPoints, pts.P.size());
    EXPECT_EQ(stFirst.virtualPoints, 0u);
    EXPECT_EQ(stFirst.storedPlaneLit, 0u);
    // Without the culling tests every point takes virtual samples, with
    // the same results.
    expectUnculledVirtualSamplesAgree(*second, pts.batch(1), params, outSecond);
    // Without normals there is no tangent plane: plain comparisons.
    std::vector<float> noNormals(pts.P.size());
    ShadowStats st;
    second->lookup(pts.batch(1, false), params, noNormals.data(), st);
    EXPECT_EQ(noNormals, outFirst);
}

TEST(SecondDepth, OccluderEdgeStillFiltersTheCoveredFraction) {
    auto map = test::writeAndOpen(slopeImage(DepthFilter::Second, true), "slope_occluder.exr");
    ASSERT_TRUE(map);
    Surface pts = pointsOnSlope(1000, 60, 68, 5);
    pts.P.push_back(Vec3(30, 30, 59));  // wholly behind the occluder
    pts.du.push_back(pts.du[0]);
    pts.dv.push_back(pts.dv[0]);
    pts.N.push_back(pts.N[0]);
    pts.P.push_back(Vec3(100, 30, 80));  // wholly on the open slope
    pts.du.push_back(pts.du[0]);
    pts.dv.push_back(pts.dv[0]);
    pts.N.push_back(pts.N[0]);
    pts.P.push_back(Vec3(30, 30, 59));  // behind the occluder, facing away from the light
    pts.du.push_back(pts.du[0]);
    pts.dv.push_back(pts.dv[0]);
    pts.N.push_back(-pts.N[0]);
    ShadowParams params;
    params.tileCulling = false;
    std::vector<float> out(pts.P.size());
    ShadowStats st;
    map->lookup(pts.batch(2), params, out.data(), st);
    const size_t n = pts.P.size();
    double meanErr = 0;
    for (size_t i = 0; i + 3 < n; ++i) {
        // The region is [x-2, x+2) (4-texel footprint, 16 samples in 4x4
        // strata): shadowed fraction = the part left of x = 64.
        double p = std::clamp((64.0 - (pts.P[i].x - 2.0)) / 4.0, 0.0, 1.0);
        EXPECT_NEAR(out[i], p, 0.25 + 1e-6) << pts.P[i].x;
        meanErr += out[i] - p;
    }
    EXPECT_NEAR(meanErr / double(n - 3), 0.0, 0.02);
    // Wholly behind the occluder: shadowed, confirmed by virtual samples
    // when the point faces the light, at once (Figure 10) when it does not.
    EXPECT_EQ(out[n - 3], 1.0f);
    EXPECT_EQ(out[n - 2], 0.0f);
    EXPECT_EQ(out[n - 1], 1.0f);
    EXPECT_EQ(st.secondShadowed, 1u);
    EXPECT_GT(st.virtualPoints, 0u);
}

TEST(SecondDepth, PerspectivePlaneIsLinearInScreenSpace) {
    // A pinhole light at the origin, 90 degrees: raster x = (x/z + 1)/2 * W,
    // y = (1 - y/z)/2 * H. The receiver plane z = 20 + 0.8 x is stored by
    // casting a ray through every texel centre: with sx = x/z there,
    // z = 20 / (1 - 0.8 sx).
    const int res = 128;
    DepthImage img(res, res);
    img.ndcFromWorld = test::ndcFromCamera90();
    img.filter = DepthFilter::Second;
    for (int y = 0; y < res; ++y)
        for (int x = 0; x < res; ++x) {
            double sx = (double(x) + 0.5) / res * 2.0 - 1.0;
            img.at(x, y) = float(20.0 / (1.0 - 0.8 * sx));
        }
    auto map = test::writeAndOpen(img, "persp_second.exr");
    ASSERT_TRUE(map);
    Surface pts;
    Rng rng(9);
    for (int i = 0; i < 300; ++i) {
        // Points on the plane seen within the central part of the map.
        float sx = -0.6f + 1.2f * rng.uniform(), sy = -0.6f + 1.2f * rng.uniform();
        float z = 20.0f / (1.0f - 0.8f * sx);
        pts.P.push_back(Vec3(sx * z, sy * z, z));
        // Footprints of about 6 texels: 16 samples straddle P, so the plain
        // comparisons are mixed (Fig. 10 trusts unanimous ones).
        pts.du.push_back(Vec3(2, 0, 1.6f));
        pts.dv.push_back(Vec3(0, 2, 0));
        pts.N.push_back(normalize(Vec3(0.8f, 0, -1)));
    }
    ShadowParams params;  // no bias
    std::vector<float> out(pts.P.size());
    ShadowStats st;
    map->lookup(pts.batch(3), params, out.data(), st);
    for (size_t i = 0; i < out.size(); ++i) EXPECT_EQ(out[i], 0.0f) << i;
    // Stored as 1/z-linear blocks, the plane is recognised without samples
    // (the two tests agree: culling off takes virtual samples everywhere).
    EXPECT_EQ(st.virtualPoints + st.storedPlaneLit, pts.P.size());
    EXPECT_GT(st.storedPlaneLit, 0u);
    expectUnculledVirtualSamplesAgree(*map, pts.batch(3), params, out);

    // An occluder's back face at depth 10 over texel columns < 40: receiver
    // points whose region is centred on that edge are half in shadow, and
    // only a correct plane (in 1/z) gets their lit half lit and their
    // shadowed half shadowed.
    for (int y = 0; y < res; ++y)
        for (int x = 0; x < 40; ++x) img.at(x, y) = 10;
    auto edged = test::writeAndOpen(img, "persp_second_edge.exr");
    ASSERT_TRUE(edged);
    Surface edge;
    for (int i = 0; i < 200; ++i) {
        const float sx = 40.0f / 64.0f - 1.0f + 0.02f * (rng.uniform() - 0.5f), sy = -0.5f + rng.uniform();
        const float z = 20.0f / (1.0f - 0.8f * sx);
        edge.P.push_back(Vec3(sx * z, sy * z, z));
        edge.du.push_back(Vec3(2, 0, 1.6f));
        edge.dv.push_back(Vec3(0, 2, 0));
        edge.N.push_back(normalize(Vec3(0.8f, 0, -1)));
    }
    std::vector<float> half(edge.P.size());
    ShadowStats est;
    edged->lookup(edge.batch(4), params, half.data(), est);
    double mean = 0;
    for (float v : half) mean += v;
    mean /= double(half.size());
    EXPECT_NEAR(mean, 0.5, 0.1);
    EXPECT_EQ(est.virtualPoints, edge.P.size());
}

TEST(SecondDepth, BlocksStoreThePlaneTheirDepthsLieOn) {
    // Orthographic (q = z) and perspective (q = 1/z) planes fit; an empty
    // texel, a bump larger than kPlaneFit and a step do not.
    for (auto coord : {ShadowTile::DepthCoordinate::Depth, ShadowTile::DepthCoordinate::InverseDepth}) {
        const bool inverse = coord == ShadowTile::DepthCoordinate::InverseDepth;
        ShadowTile t;
        t.width = t.height = 32;
        t.z.resize(1024);
        auto q = [](int x, int y) { return 0.05 + 0.0007 * x - 0.0003 * y; };
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 32; ++x) t.z[size_t(y * 32 + x)] = float(inverse ? 1.0 / q(x, y) : q(x, y));
        t.z[size_t(1 * 32 + 9)] = kInfinity;                           // block 1: an empty texel
        t.z[size_t(9 * 32 + 3)] *= 1.0f + 10 * ShadowTile::kPlaneFit;  // block 4: a bump
        for (int y = 16; y < 24; ++y) t.z[size_t(y * 32 + 20)] *= 2;   // block 10: a step
        t.computeBlocks(coord);
        for (int b = 0; b < 16; ++b) {
            const int bx = (b % 4) * 8, by = (b / 4) * 8;
            if (b == 1 || b == 4 || b == 10) {
                EXPECT_TRUE(std::isnan(t.planeQ0[b])) << b;
                continue;
            }
            ASSERT_FALSE(std::isnan(t.planeQ0[b])) << b;
            for (int j = 0; j < 8; ++j)
                for (int i = 0; i < 8; ++i)
                    EXPECT_NEAR(t.planeQ0[b] + t.planeGx[b] * float(i) + t.planeGy[b] * float(j), q(bx + i, by + j),
                                1e-6 * q(0, 0))
                        << b << " " << i << " " << j;
        }
        // Without a coordinate no block is fitted.
        t.computeBlocks();
        for (int b = 0; b < 16; ++b) EXPECT_TRUE(std::isnan(t.planeQ0[b])) << b;
    }
}

ShadowBatch subBatch(const Surface& s, size_t first, size_t n, uint32_t seed) {
    ShadowBatch b;
    b.count = int(n);
    b.P = s.P.data() + first;
    b.dPdu_du = s.du.data() + first;
    b.dPdv_dv = s.dv.data() + first;
    b.N = s.N.data() + first;
    b.seed = seed;
    return b;
}

/// Grids of 4 x 4 points, one texel apart, on the open floor z = 50 +
/// 0.3 x of slopeImage(), their first points uniform in [x0, x0 + xSpan) x
/// [y0, y0 + ySpan), as a renderer passes a floor's grids; each normal
/// turned by up to `jitter` (drawn from `rng` only when non-zero).
void appendFloorGrids(Surface& pts, Rng& rng, int grids, float x0, float xSpan, float y0, float ySpan,
                      float jitter = 0) {
    const Vec3 du(1, 0, 0.3f), dv(0, 1, 0);
    const Vec3 floorN = normalize(cross(du, dv)) * -1.0f;
    for (int g = 0; g < grids; ++g) {
        const float gx = x0 + xSpan * rng.uniform(), gy = y0 + ySpan * rng.uniform();
        for (int k = 0; k < 16; ++k) {
            const float x = gx + float(k % 4), y = gy + float(k / 4);
            pts.P.push_back(Vec3(x, y, 50 + 0.3f * x));
            pts.du.push_back(du);
            pts.dv.push_back(dv);
            pts.N.push_back(jitter == 0 ? floorN
                                        : normalize(floorN + Vec3(jitter * (rng.uniform() - 0.5f),
                                                                  jitter * (rng.uniform() - 0.5f), 0)));
        }
    }
}

TEST(SecondDepth, AFlatGridIsLitFromTheStoredPlanesAWholeGridAtATime) {
    // A shaded grid's normals are computed point by point, so the tangent
    // planes of a flat grid differ a little (here by 1e-5 in the normal, a
    // few hundred times float rounding). The planes through its points
    // then differ little near the grid and a lot far from it: bounded
    // about the map's origin (x near 100 texels here) the difference
    // exceeded what the stored-plane test allows and every grid fell back
    // to testing its points one by one; bounded about the grid's own
    // region it is decided whole. Every point is lit either way.
    auto map = test::writeAndOpen(slopeImage(DepthFilter::Second, true), "grid_planes.exr");
    ASSERT_TRUE(map);
    Surface pts;
    Rng rng(8);
    appendFloorGrids(pts, rng, 24, 76, 40, 8, 44, 1e-5f);
    ShadowParams params;
    std::vector<float> out(pts.P.size(), -1.0f);
    ShadowStats st;
    for (size_t first = 0; first < pts.P.size(); first += 16)
        map->lookup(subBatch(pts, first, 16, uint32_t(first)), params, out.data() + first, st);
    for (size_t i = 0; i < pts.P.size(); ++i) EXPECT_EQ(out[i], 0.0f) << pts.P[i].x;
    EXPECT_EQ(st.storedPlaneLit, pts.P.size());
    EXPECT_EQ(st.storedPlaneGridPoints, pts.P.size());
}

TEST(SecondDepth, CullingNeverChangesAResult) {
    // The open floor z = 50 + 0.3 x stored as itself, an occluder's back
    // face at z = 12 over x < 64 (slopeImage). Receivers, in grids of 16
    // points as a renderer passes them:
    //  - the floor itself, lit from the planes its blocks store, whole
    //    grids at once where every block they reach stores the floor;
    //  - steep light-facing planes whose points lie beyond every stored
    //    depth of their regions (and, in the second group, of their whole
    //    tile) but whose planes rise in front of the floor within the
    //    region. A depth-range cull alone would call them shadowed; their
    //    virtual samples light a part of each.
    auto map = test::writeAndOpen(slopeImage(DepthFilter::Second, true), "cull_exact.exr");
    ASSERT_TRUE(map);
    Surface pts;
    Rng rng(21);
    appendFloorGrids(pts, rng, 40, 4, 116, 4, 52);
    const size_t steepFrom = pts.P.size();
    // (offset above the floor, slope, first x): within +-2 texels the
    // stored floor rises at most 0.75 above its depth at x, and every 8x8
    // block it reaches at most 2.85; the tiles over x < 128 hold at most
    // 88.25, which x >= 100 and an offset of 12 clear.
    const float groups[2][3] = {{3.5f, -3.0f, 70.0f}, {12.0f, -10.0f, 100.0f}};
    for (const auto& grp : groups)
        for (int k = 0; k < 32; ++k) {
            // The second group's grids are small enough for their bound
            // (regions of up to 22 texels, from 3-D footprint lengths) to
            // stay inside the map: a whole grid reaches the tile test.
            const bool whole = grp[2] >= 100;
            const float x = grp[2] + (whole ? 3.0f : 50.0f) * rng.uniform();
            const float y = whole ? 28 + 6 * rng.uniform() : 8 + 48 * rng.uniform();
            pts.P.push_back(Vec3(x, y, 50 + 0.3f * x + grp[0]));
            pts.du.push_back(Vec3(4, 0, 4 * grp[1]));
            pts.dv.push_back(Vec3(0, 4, 0));
            pts.N.push_back(normalize(Vec3(grp[1], 0, -1)));  // the plane's, towards the light (-z)
        }
    ShadowParams on, off;
    off.tileCulling = false;
    std::vector<float> outOn(pts.P.size()), outOff(pts.P.size());
    ShadowStats stOn, stOff;
    for (size_t first = 0; first < pts.P.size(); first += 16) {
        map->lookup(subBatch(pts, first, 16, uint32_t(first)), on, outOn.data() + first, stOn);
        map->lookup(subBatch(pts, first, 16, uint32_t(first)), off, outOff.data() + first, stOff);
    }
    EXPECT_EQ(outOn, outOff);
    size_t openFloor = 0;  // floor points well clear of the occluder
    for (size_t i = 0; i < steepFrom; ++i) openFloor += pts.P[i].x > 70;
    EXPECT_GT(stOn.storedPlaneLit, openFloor * 3 / 4);
    EXPECT_EQ(stOff.storedPlaneLit, 0u);
    int partial = 0;
    for (size_t i = steepFrom; i < pts.P.size(); ++i) partial += outOff[i] > 0 && outOff[i] < 1;
    EXPECT_GT(partial, 48);  // of 64: the test must reach the case it is about
    for (size_t i = 0; i < steepFrom; ++i) {
        if (pts.P[i].x > 70) {
            EXPECT_EQ(outOn[i], 0.0f) << pts.P[i].x;
        }
    }
}

}  // namespace
}  // namespace umbra
