/* The part of the RenderMan C binding (RI spec 3.2, Appendix C) a
 * `Procedural "DynamicLoad"` DSO can call back into while umbra runs its
 * Subdivide: the requests below, each going to the procedural's expansion
 * exactly as its RIB form would. C and C++. A DSO is built against this
 * header and links against nothing; the symbols are the umbra program's
 * (it exports them). Calls outside a Subdivide are ignored. Parameter
 * lists end with RI_NULL; values are read by each token's declaration
 * (standard, or inline: "uniform float Ka").
 *
 * A DSO defines, with C linkage:
 *   RtPointer ConvertParameters(RtString datablock);
 *   RtVoid Subdivide(RtPointer data, RtFloat detail);
 *   RtVoid Free(RtPointer data);
 */
#ifndef UMBRA_GEOMETRY_RI_H
#define UMBRA_GEOMETRY_RI_H

#ifdef __cplusplus
extern "C" {
#endif

typedef short RtBoolean;
typedef int RtInt;
typedef float RtFloat;
typedef char* RtToken;
typedef RtFloat RtColor[3];
typedef RtFloat RtPoint[3];
typedef RtFloat RtMatrix[4][4];
typedef RtFloat RtBound[6];
typedef char* RtString;
typedef void* RtPointer;
typedef void RtVoid;
typedef RtVoid (*RtProcSubdivFunc)(RtPointer data, RtFloat detail);
typedef RtVoid (*RtProcFreeFunc)(RtPointer data);

#define RI_NULL ((RtToken)0)

RtVoid RiAttributeBegin(void);
RtVoid RiAttributeEnd(void);
RtVoid RiTransformBegin(void);
RtVoid RiTransformEnd(void);
RtVoid RiColor(RtColor color);
RtVoid RiOpacity(RtColor color);
RtVoid RiTranslate(RtFloat dx, RtFloat dy, RtFloat dz);
RtVoid RiRotate(RtFloat angle, RtFloat dx, RtFloat dy, RtFloat dz);
RtVoid RiScale(RtFloat sx, RtFloat sy, RtFloat sz);
RtVoid RiConcatTransform(RtMatrix transform);
RtVoid RiSurface(RtToken name, ...);
RtVoid RiSurfaceV(RtToken name, RtInt n, RtToken tokens[], RtPointer values[]);
RtVoid RiSphere(RtFloat radius, RtFloat zmin, RtFloat zmax, RtFloat thetamax, ...);
RtVoid RiSphereV(RtFloat radius, RtFloat zmin, RtFloat zmax, RtFloat thetamax, RtInt n, RtToken tokens[],
                 RtPointer values[]);
RtVoid RiPolygon(RtInt nvertices, ...);
RtVoid RiPolygonV(RtInt nvertices, RtInt n, RtToken tokens[], RtPointer values[]);

/* A nested procedural: `data` is what the RIB form's string array holds
 * (an RtString array), `subdivfunc` one of the three below. A DSO's own
 * subdivide function is not supported (reported, skipped); `freefunc` is
 * called at once, as umbra copies the strings. */
RtVoid RiProcedural(RtPointer data, RtBound bound, RtProcSubdivFunc subdivfunc, RtProcFreeFunc freefunc);
RtVoid RiProcDelayedReadArchive(RtPointer data, RtFloat detail);
RtVoid RiProcRunProgram(RtPointer data, RtFloat detail);
RtVoid RiProcDynamicLoad(RtPointer data, RtFloat detail);
RtVoid RiProcFree(RtPointer data);

#ifdef __cplusplus
}
#endif

#endif /* UMBRA_GEOMETRY_RI_H */
