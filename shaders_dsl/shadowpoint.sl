/* shadowpoint: pointlight with six shadow maps, one per cube face along
   the "world" axes (sfpx: the map looking down world +x, sfnx down -x,
   ...), as Pixar's shadowpoint picks them and as the six maps are made:
   cameras along the world axes, whatever the light's own transform.
   umbra extension: "shadowname" names one cube map holding all six faces
   (what "shadowname" "auto" renders); it takes precedence when set. */
#define SHADOW_ARGS "samples", samples, "width", width, "blur", blur, \
                    "bias", bias, "bias0", bias0, "bias1", bias1

light shadowpoint(float intensity = 1; color lightcolor = 1;
                  point from = point "shader" (0, 0, 0);
                  string sfpx = "", sfnx = "", sfpy = "", sfny = "", sfpz = "", sfnz = "";
                  string shadowname = "";
                  float samples = 16, width = 1, blur = 0, bias = 0, bias0 = 0, bias1 = 0;)
{
    illuminate(from) {
        vector Ls = vtransform("world", L);
        float ax = abs(xcomp(Ls)), ay = abs(ycomp(Ls)), az = abs(zcomp(Ls));
        float shad = 0;
        if (shadowname != "") {
            shad = shadow(shadowname, Ps, SHADOW_ARGS);
        } else if (ax >= ay && ax >= az) {
            if (xcomp(Ls) > 0) {
                if (sfpx != "") shad = shadow(sfpx, Ps, SHADOW_ARGS);
            } else {
                if (sfnx != "") shad = shadow(sfnx, Ps, SHADOW_ARGS);
            }
        } else if (ay >= az) {
            if (ycomp(Ls) > 0) {
                if (sfpy != "") shad = shadow(sfpy, Ps, SHADOW_ARGS);
            } else {
                if (sfny != "") shad = shadow(sfny, Ps, SHADOW_ARGS);
            }
        } else {
            if (zcomp(Ls) > 0) {
                if (sfpz != "") shad = shadow(sfpz, Ps, SHADOW_ARGS);
            } else {
                if (sfnz != "") shad = shadow(sfnz, Ps, SHADOW_ARGS);
            }
        }
        Cl = (1 - shad) * intensity * lightcolor / (L . L);
    }
}
