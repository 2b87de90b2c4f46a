/* benchspot: the standard spotlight with a shadow map looked up with a
   given number of samples, written out so that every renderer of the
   production benchmark runs the same light. */
light benchspot(float intensity = 1; color lightcolor = 1;
                point from = point "shader" (0, 0, 0); point to = point "shader" (0, 0, 1);
                float coneangle = radians(30); float conedeltaangle = radians(5);
                float beamdistribution = 2; string shadowname = ""; float samples = 16)
{
    uniform vector A = (to - from) / length(to - from);
    illuminate(from, A, coneangle) {
        float cosangle = L . A / length(L);
        float atten = pow(cosangle, beamdistribution) / (L . L);
        atten *= smoothstep(cos(coneangle), cos(coneangle - conedeltaangle), cosangle);
        if (shadowname != "")
            atten *= 1 - shadow(shadowname, Ps, "samples", samples);
        Cl = atten * intensity * lightcolor;
    }
}
