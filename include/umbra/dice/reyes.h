#pragma once
// The split/dice decision of the REYES loop (Cook, Carpenter, Catmull 1987),
// independent of any particular primitive family.
//
// REYES terms, defined once here:
//  - bound: a primitive's object-space box (Primitive::bound), taken to
//    camera space and padded by the displacement bound;
//  - cull: drop a primitive whose bound cannot reach any visible sample
//    (outside the raster window, entirely before the near or beyond the far
//    clipping plane);
//  - split: replace a primitive by smaller pieces of the same kind
//    (Primitive::split) when it is too big on screen for one grid, or not
//    diceable as it is;
//  - dice: evaluate the primitive on an nu x nv parametric lattice, a
//    *grid* (geometry/grid.h) whose cells are *micropolygons*, chosen so each
//    micropolygon covers about `shadingRate` pixels of area;
//  - eye split: a perspective projection divides by camera z, so geometry
//    whose bound crosses the eye plane (z near 0) cannot be measured or
//    projected; it is split until its pieces lie on one side, at most
//    `maxEyeSplits` times, after which the remaining pieces are culled with
//    a warning (RenderMan's "eyesplits" limit).

#include "umbra/geometry/primitive.h"
#include "umbra/util/error.h"
#include "umbra/util/math.h"

namespace umbra::dice {

/// Everything the decision needs about the camera and the attributes of the
/// primitive being decided.
struct DiceParams {
    Mat4 cameraFromObject;              // affine
    Mat4 rasterFromCamera;              // projective: camera space -> raster pixels (x right, y down or up)
    /// The raster region where samples can be affected, in pixels: xmin
    /// xmax ymin ymax (the crop window plus the pixel filter's radius).
    float rasterWindow[4] = {-kInfinity, kInfinity, -kInfinity, kInfinity};
    float shadingRate = 1.0f;           // micropolygon area in pixels
    int gridSize = 256;                 // max micropolygons per grid
    float nearClip = 1e-10f, farClip = 1e30f;  // camera-space z
    int maxEyeSplits = 10;
    bool orthographic = false;
    float displacementBound = 0;        // camera-space padding of every bound
    int testGrid = 8;                   // lattice used to measure a primitive on screen
    /// When > 0 (depth passes): the most, in pixels, a micropolygon may
    /// stand off the surface it stands for, across the image or in depth
    /// (measured in pixel widths at that depth). The grid is then no finer
    /// than that needs, as well as no finer than `shadingRate` gives: large
    /// smooth surfaces get large micropolygons. Measured from the test
    /// lattice's second differences; leave 0 when displacement may add
    /// detail the lattice cannot see.
    float flatness = 0;
    /// GeometricApproximation "flatness" (RI Spec 3.2: the greatest
    /// distance, in raster pixels, between the true surface and its
    /// polygonal approximation). When > 0 the grid is at least as fine as
    /// that needs, measured on the test lattice (standOffCounts(): second
    /// differences along the surface normal, in pixels at their depth): the counts are the finer of the
    /// shading rate's and this one's, so a coarse ShadingRate still keeps
    /// silhouettes within the stand-off. Flat surfaces need nothing extra.
    float maxStandOff = 0;
    /// The most, in radians, one micropolygon edge may turn along the
    /// surface (measured on the test lattice in camera space): a floor on
    /// the counts whatever the shading rate, so a huge ShadingRate dices a
    /// sphere into at least 8 x 4 micropolygons instead of a 1 x 1 grid
    /// that covers nothing. 0 turns the floor off.
    float maxTurn = kPi / 4;
    /// Attribute "dice" "binary": every grid's nu and nv are powers of two
    /// (PRMan's binary dicing), so grids that share an edge after splits
    /// place the same vertices along it. A grid whose rounded-up counts
    /// exceed gridSize is split instead.
    bool binary = false;
    /// A piece that moves (motion blur): its camera-space bound over the
    /// whole shutter, padded as cameraBound() pads. Culling and the eye
    /// plane test it; the dicing rate is measured at the shutter's opening
    /// (cameraFromObject), where the grid is shaded. Empty: not moving.
    Bound3 sweep;
    /// The raster area, in pixels, that the pieces this piece splits into
    /// may need between them (rasterNeed(); shared out by the bucket
    /// scheduler, Frame::shareBudget). A piece whose budget is less than two
    /// grids' worth (2 x shadingRate x gridSize) is diced now, coarser than
    /// the shading rate if it must, with a warning: a surface whose pieces
    /// all stay in view (folded on itself, corrupt control points) would
    /// otherwise multiply them without end. Eye-plane splits and fixed
    /// counts do not ask it.
    double splitBudget = kInfinity;
    /// What the piece itself needs, in the same pixels (rasterNeed()). A
    /// piece whose budget is spent but that needs no more than one grid's
    /// worth of pixels is diced into one grid without a warning: its
    /// micropolygons are then no larger than the shading rate asks.
    double pieceNeed = kInfinity;
};

/// The three outcomes of the REYES loop for one primitive.
enum class Decision { Cull, Split, Dice };

/// What to do with one primitive.
struct DiceResult {
    Decision decision = Decision::Cull;
    bool splitU = true;   // Split: cut across u (halve the u range) rather than v
    bool eyeSplit = false;// Split because the bound crosses the eye plane (counts towards maxEyeSplits)
    int nu = 0, nv = 0;   // Dice: micropolygons along u and v
};

/// The z of the eye plane below which a perspective projection is not
/// trusted (camera units): min(nearClip, 1e-3) but at least 1e-6.
float eyePlaneZ(const DiceParams& p);

/// Camera-space bound of an object-space bound, padded by the
/// displacement bound.
Bound3 cameraBound(const Bound3& objectBound, const DiceParams& p);
/// The same of a primitive as this camera's eye sees it
/// (geometry::Primitive::cameraBound: a point's disc faces it).
Bound3 cameraBound(const geometry::Primitive& prim, const DiceParams& p);

/// Raster-space bound for bucket assignment: x, y in pixels, z the camera
/// z range. When the bound crosses the eye plane (perspective) x and y are
/// unbounded (-inf, inf). Empty for an empty input.
Bound3 rasterBound(const Bound3& objectBound, const DiceParams& p);

/// rasterBound() of a camera-space bound (e.g. DiceParams::sweep).
Bound3 rasterBoundOfCamera(const Bound3& cameraBound, const DiceParams& p);

/// The raster area, in pixels, a primitive needs diced inside
/// DiceParams::rasterWindow, measured on its test lattice: the area its
/// cells cover there (each cut into two triangles clipped to the window;
/// layers that overlap on screen each count), and a strip one grid's side
/// wide along every side of the window the lattice crosses (a piece
/// reaching into the frame is cut along its edge into pieces about a grid
/// wide, however little of them shows). The pieces of a surface that tile
/// it add up to its need; pieces that pile up in view each keep it.
/// Negative when it cannot be measured: the primitive is not diceable, or
/// (perspective) it reaches behind the eye plane.
double rasterNeed(const geometry::Primitive& prim, const DiceParams& p);

/// The most a piece with this raster bound can need inside
/// DiceParams::rasterWindow: the bound's area there, and the same strips
/// along the sides it crosses as rasterNeed(). What a piece that cannot be
/// measured needs, and a cap on what a lattice near a perspective eye
/// measures. Finite whenever the window is.
double boundNeed(const Bound3& rasterBound, const DiceParams& p);

/// True when the camera-space bound cannot reach the raster window or the
/// clipping range: tested against the window's four side planes in camera
/// space (no division, so it works for bounds behind the eye too).
bool outsideView(const Bound3& cameraBound, const DiceParams& p);

/// Decides whether `prim` (bounded as the camera sees it, cameraBound()) is
/// culled, split or diced. `eyeSplits` is how many eye splits produced it;
/// the caller passes result.eyeSplit ? eyeSplits + 1 : eyeSplits to the
/// pieces. The limit (DiceParams::maxEyeSplits) does not stop a group of
/// points, which comes down to single points. `diag` (optional) gets a
/// once-per-run warning when geometry still across the eye plane is culled.
DiceResult decide(const geometry::Primitive& prim, const DiceParams& p, int eyeSplits = 0,
                  Diagnostics* diag = nullptr);

/// Longest raster lengths along u and along v of an (nu+1) x (nv+1) lattice
/// of raster positions (row after row, u fastest): the largest polyline
/// length over rows, and over columns, in pixels (x and y only).
void rasterLengths(const Vec3* raster, int nu, int nv, float* lenU, float* lenV);

/// The fewest micropolygons along u and v (at least 1) whose triangles
/// stand off a surface by at most `flatness` pixels, from an (n+1) x (n+1)
/// lattice of it (row after row, u fastest) in "pixel space": raster x and
/// y, and depth in pixel widths at that depth. A chord's bend grows with
/// the square of its length, so the lattice's largest second differences
/// along u and v, and its largest twist (a cell off its diagonal), give
/// the counts; see reyes.cpp for the budget.
void flatnessCounts(const Vec3* pixelSpace, int n, float flatness, float* countU, float* countV);

/// The fewest micropolygons along u and v (at least 1) whose triangles
/// stand off a surface by at most `standOff` pixels, from an (n+1) x (n+1)
/// lattice of it in camera space (row after row, u fastest) and how many
/// pixels a camera unit spans at each lattice point: as flatnessCounts(),
/// but only the part of each second difference along the surface normal
/// counts, so a plane (however foreshortened) needs 1 x 1.
/// GeometricApproximation "flatness" (DiceParams::maxStandOff).
void standOffCounts(const Vec3* cameraSpace, const float* pixelsPerUnit, int n, float standOff, float* countU,
                    float* countV);

/// The fewest micropolygons along u and v (at least 1) for which no edge
/// turns by more than `maxTurn` radians, from an (n+1) x (n+1) lattice of
/// the surface (row after row, u fastest; any space that keeps angles,
/// e.g. camera space): the largest total turning of a row (a column),
/// divided by `maxTurn`. A full circle at pi/4 gives 8, a half circle 4, a
/// straight line 1.
void turningCounts(const Vec3* lattice, int n, float maxTurn, float* countU, float* countV);

}  // namespace umbra::dice
