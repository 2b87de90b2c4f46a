/* spotlight: a cone of light with a soft edge and a beam falloff (RI spec 3.2). */
light spotlight(float intensity = 1; color lightcolor = 1;
                point from = point "shader" (0, 0, 0);
                point to = point "shader" (0, 0, 1);
                float coneangle = radians(30);
                float conedeltaangle = radians(5);
                float beamdistribution = 2;)
{
    uniform vector A = (to - from) / length(to - from);
    float cosoutside = cos(coneangle), cosinside = cos(coneangle - conedeltaangle);
    float atten, cosangle;
    illuminate(from, A, coneangle) {
        cosangle = L . A / length(L);
        atten = pow(cosangle, beamdistribution) / (L . L);
        atten *= smoothstep(cosoutside, cosinside, cosangle);
        Cl = atten * intensity * lightcolor;
    }
}
