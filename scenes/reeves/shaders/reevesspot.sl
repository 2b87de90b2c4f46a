/* reevesspot: a spotlight whose shadow() call exposes every parameter of
   Reeves, Salesin & Cook (1987) Figure 4, for the figures of docs/shadows.md.
   samples = NumSamples, width = ResFactor, bias0/bias1 = the stochastic bias
   range (world units), minsamples = MinSamples, minsize = MinSize (texels),
   sampling = Figure 3 a/b/c ("uniform", "gaussian", "jittered").
   shadowonly = 1 drops the cone and distance fall-off so that Cl is the
   shadow component alone (Reeves Figure 6), for use with shadowmatte. */
light reevesspot(float intensity = 1; color lightcolor = 1;
                 point from = point "shader" (0, 0, 0);
                 point to = point "shader" (0, 0, 1);
                 float coneangle = radians(30);
                 float conedeltaangle = radians(5);
                 float beamdistribution = 2;
                 string shadowname = "";
                 float samples = 16, width = 1, blur = 0, bias = 0, bias0 = 0, bias1 = 0;
                 float minsamples = 2, minsize = 2;
                 string sampling = "jittered", filter = "box";
                 float shadowonly = 0;)
{
    uniform vector A = (to - from) / length(to - from);
    float cosoutside = cos(coneangle), cosinside = cos(coneangle - conedeltaangle);
    float atten, cosangle, unshadowed;
    illuminate(from, A, coneangle) {
        cosangle = L . A / length(L);
        atten = pow(cosangle, beamdistribution) / (L . L);
        atten *= smoothstep(cosoutside, cosinside, cosangle);
        unshadowed = 1;
        if (shadowname != "")
            unshadowed = 1 - shadow(shadowname, Ps, "samples", samples, "width", width, "blur", blur,
                                    "bias", bias, "bias0", bias0, "bias1", bias1,
                                    "minsamples", minsamples, "minsize", minsize,
                                    "sampling", sampling, "filter", filter);
        if (shadowonly != 0)
            Cl = unshadowed * lightcolor;
        else
            Cl = unshadowed * atten * intensity * lightcolor;
    }
}
