#pragma once
// The built-in functions of the shading language: identifiers shared by the
// code generator (which resolves overloads against `builtinTable()`) and
// the interpreter (which implements each id over a grid).

#include "slc.h"

#include <vector>

namespace umbra::shading {

/// Built-in function ids (Instr::sub of Op::Call).
enum class Bi : int16_t {
    // float -> float, per point
    Sin, Cos, Tan, Asin, Acos, Atan, Exp, Log, Sqrt, InvSqrt, Abs, Sign, Floor, Ceil, Round, Radians, Degrees,
    // float, float -> float
    Atan2, Pow, PowT, LogBase, Mod, MinF, MaxF, Step,
    MinT, MaxT, ClampF, ClampT, MixF, MixT, MixTF, SmoothStep, FilterStep, FilterStep2,
    AbsT, FloorT, CeilT, ModT,
    SplineF, SplineT, SplineBasisF, SplineBasisT,
    // geometry
    Xcomp, Ycomp, Zcomp, SetXcomp, SetYcomp, SetZcomp, CompM, SetCompM,
    Length, Distance, Normalize, FaceForward, FaceForward3, Reflect, Refract, Fresnel, FresnelRT,
    Transform, TransformFT, TransformM, VTransform, VTransformFT, VTransformM, NTransform, NTransformFT, NTransformM,
    TransformSM, VTransformSM, NTransformSM,
    CTransform, CTransformFT, CalculateNormal, Area, Depth, PtLined, Rotate3,
    DuF, DvF, DuT, DvT, DerivF, DerivT,
    // matrices
    Determinant, TranslateM, RotateM, ScaleM, SpaceMatrix,
    // strings
    Concat, Format, Printf, Match,
    // noise
    NoiseF1, NoiseF2, NoiseF3, NoiseF4, NoiseT1, NoiseT2, NoiseT3, NoiseT4,
    PNoiseF1, PNoiseF2, PNoiseF3, PNoiseF4, PNoiseT1, PNoiseT2, PNoiseT3, PNoiseT4,
    CellF1, CellF2, CellF3, CellF4, CellT1, CellT2, CellT3, CellT4,
    RandomF, RandomT,
    // shading
    Ambient, Diffuse, Specular, SpecularBrdf, Phong,
    TextureF, TextureC, TextureF4, TextureC4, EnvironmentF, EnvironmentC, EnvironmentF4, EnvironmentC4, Shadow, Shadow4, TextureInfo,
    // message passing
    LightSource, SurfaceMsg, DisplacementMsg, AtmosphereMsg, Incident, Opposite, Attribute, Option, RendererInfo,
    ShaderNameOf,
    // conversions
    ColorFromSpace,
    Count
};

/// One overload. Argument codes: f float, c color, p point/vector/normal,
/// t any triple (the result takes the first triple argument's type),
/// m matrix, s string, '&' before a code marks an output argument, '*'
/// accepts any remaining "name", value pairs. Return codes are the same
/// ('t' = type of the first triple argument, 'v' void).
struct BuiltinSig {
    const char* name;
    Bi id;
    const char* ret;
    const char* args;
    bool alwaysVarying = false;  // result varies per point even for uniform arguments
    bool usesLights = false;
};

const std::vector<BuiltinSig>& builtinTable();

}  // namespace umbra::shading
