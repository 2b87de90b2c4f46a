// A Procedural "DynamicLoad" DSO for procedural_test.cpp: its data block
// is a radius, and it makes the blue sphere the RunProgram generator of
// that test writes, so the two can be compared with the same inline RIB.

#include "umbra/geometry/ri.h"

#include <cstdlib>

extern "C" {

RtPointer ConvertParameters(RtString datablock) {
    auto* radius = static_cast<RtFloat*>(std::malloc(sizeof(RtFloat)));
    *radius = RtFloat(std::atof(datablock));
    return radius;
}

RtVoid Subdivide(RtPointer data, RtFloat) {
    const RtFloat r = *static_cast<RtFloat*>(data);
    RtColor blue = {0.2f, 0.4f, 0.9f};
    RiAttributeBegin();
    RiColor(blue);
    RiSphere(r, -r, r, 360.0f, RI_NULL);
    RiAttributeEnd();
}

RtVoid Free(RtPointer data) { std::free(data); }

}  // extern "C"
