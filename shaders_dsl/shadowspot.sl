/* shadowspot: spotlight attenuated by a depth-map shadow. shadowname ""
   means no shadow; samples, width, blur, bias, bias0 and bias1 go to shadow(). */
light shadowspot(float intensity = 1; color lightcolor = 1;
                 point from = point "shader" (0, 0, 0);
                 point to = point "shader" (0, 0, 1);
                 float coneangle = radians(30);
                 float conedeltaangle = radians(5);
                 float beamdistribution = 2;
                 string shadowname = "";
                 float samples = 16, width = 1, blur = 0, bias = 0, bias0 = 0, bias1 = 0;)
{
    uniform vector A = (to - from) / length(to - from);
    float cosoutside = cos(coneangle), cosinside = cos(coneangle - conedeltaangle);
    float atten, cosangle;
    illuminate(from, A, coneangle) {
        cosangle = L . A / length(L);
        atten = pow(cosangle, beamdistribution) / (L . L);
        atten *= smoothstep(cosoutside, cosinside, cosangle);
        if (shadowname != "")
            atten *= 1 - shadow(shadowname, Ps, "samples", samples, "width", width, "blur", blur,
                                "bias", bias, "bias0", bias0, "bias1", bias1);
        Cl = atten * intensity * lightcolor;
    }
}
