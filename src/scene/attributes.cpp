#include "umbra/scene/scene.h"

#include <cstring>

namespace umbra::scene {

namespace {

bool sameBasis(const Basis& a, const Basis& b) { return a.step == b.step && std::memcmp(a.m, b.m, sizeof a.m) == 0; }

}  // namespace

Attributes instanceAttributes(const Attributes& instance, const Attributes& atBegin, const Attributes& defined) {
    Attributes a = instance;
    // Each attribute the definition changed from its state at ObjectBegin.
    auto take = [](auto& into, const auto& begin, const auto& def) {
        if (!(def == begin)) into = def;
    };
    take(a.color, atBegin.color, defined.color);
    take(a.opacity, atBegin.opacity, defined.opacity);
    take(a.matte, atBegin.matte, defined.matte);
    take(a.shadingRate, atBegin.shadingRate, defined.shadingRate);
    take(a.sides, atBegin.sides, defined.sides);
    // Relative to the instance's orientation: ReverseOrientation inside the
    // definition reverses whatever the instance has.
    if (defined.insideOut != atBegin.insideOut) a.insideOut = !instance.insideOut;
    take(a.surface, atBegin.surface, defined.surface);
    take(a.displacement, atBegin.displacement, defined.displacement);
    take(a.atmosphere, atBegin.atmosphere, defined.atmosphere);
    take(a.lights, atBegin.lights, defined.lights);
    take(a.displacementBound, atBegin.displacementBound, defined.displacementBound);
    take(a.displacementBoundSpace, atBegin.displacementBoundSpace, defined.displacementBoundSpace);
    if (!sameBasis(defined.uBasis, atBegin.uBasis)) a.uBasis = defined.uBasis;
    if (!sameBasis(defined.vBasis, atBegin.vBasis)) a.vBasis = defined.vBasis;
    take(a.name, atBegin.name, defined.name);
    take(a.smoothShading, atBegin.smoothShading, defined.smoothShading);
    if (std::memcmp(defined.textureCoordinates, atBegin.textureCoordinates, sizeof a.textureCoordinates) != 0)
        std::memcpy(a.textureCoordinates, defined.textureCoordinates, sizeof a.textureCoordinates);
    take(a.solid, atBegin.solid, defined.solid);
    take(a.visibleToCamera, atBegin.visibleToCamera, defined.visibleToCamera);
    take(a.castsShadows, atBegin.castsShadows, defined.castsShadows);
    take(a.trimCurves, atBegin.trimCurves, defined.trimCurves);
    take(a.binaryDice, atBegin.binaryDice, defined.binaryDice);
    // A user attribute set inside the definition comes from a request there:
    // its location tells it from the one the definition inherited.
    for (const auto& [key, p] : defined.user) {
        auto it = atBegin.user.find(key);
        if (it == atBegin.user.end() || it->second.loc.file != p.loc.file || it->second.loc.line != p.loc.line ||
            it->second.loc.column != p.loc.column)
            a.user[key] = p;
    }
    return a;
}

}  // namespace umbra::scene
