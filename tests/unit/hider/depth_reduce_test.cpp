// Depth mode: how a pixel's samples become its depth (RenderMan's
// "depthfilter" min / max / average), and the single-layer baseline.

#include "umbra/film/film.h"
#include "umbra/hider/sample_buffer.h"

#include <gtest/gtest.h>

using namespace umbra;
using namespace umbra::hider;

namespace {

/// A flat 1x1-micropolygon grid over raster [x0,x1] x [y0,y1] at depth z.
struct Quad {
    Vec3 P[4];
    MicroGrid grid(uint64_t id) const {
        MicroGrid g;
        g.nu = g.nv = 1;
        g.P = P;
        g.id = id;
        return g;
    }
    Quad(float x0, float y0, float x1, float y1, float z) {
        P[0] = {x0, y0, z};
        P[1] = {x1, y0, z};
        P[2] = {x0, y1, z};
        P[3] = {x1, y1, z};
    }
};

/// Pixel (0,0) with 2x2 regular samples at x = 0.25 and 0.75: a near quad
/// covers the left column (z = 3), a far one the whole pixel (z = 7).
float reducedDepth(SampleBufferConfig::DepthReduce reduce, int layers, float* z2) {
    SampleBufferConfig c;
    c.x0 = 0;
    c.y0 = 0;
    c.x1 = 1;
    c.y1 = 1;
    c.margin = 0;
    c.xSamples = c.ySamples = 2;
    c.jitter = false;
    c.mode = HiderMode::Depth;
    c.depthReduce = reduce;
    c.depthLayers = layers;
    SampleBuffer buffer;
    buffer.reset(c);
    Quad nearLeft(-1, -1, 0.5f, 2, 3), farAll(-1, -1, 2, 2, 7);
    buffer.sample(nearLeft.grid(1));
    buffer.sample(farAll.grid(2));
    float crop[4] = {0, 1, 0, 1};
    film::Film film(1, 1, crop, *film::PixelFilter::create("box", 1, 1), {}, film::FilmContent::DepthPair);
    buffer.resolve(film);
    *z2 = film.z2(0, 0);
    return film.z(0, 0);
}

}  // namespace

TEST(DepthReduce, MinMaxAverageOfAPixelsSamples) {
    using R = SampleBufferConfig::DepthReduce;
    float z2;
    EXPECT_FLOAT_EQ(reducedDepth(R::Min, 2, &z2), 3.0f);
    EXPECT_FLOAT_EQ(z2, 7.0f);  // behind the near quad: the far one
    EXPECT_FLOAT_EQ(reducedDepth(R::Max, 2, &z2), 7.0f);
    EXPECT_FLOAT_EQ(reducedDepth(R::Average, 2, &z2), 5.0f);
}

TEST(DepthReduce, SingleLayerKeepsNoSecondDepth) {
    float z2;
    EXPECT_FLOAT_EQ(reducedDepth(SampleBufferConfig::DepthReduce::Min, 1, &z2), 3.0f);
    EXPECT_EQ(z2, std::numeric_limits<float>::infinity());
}
