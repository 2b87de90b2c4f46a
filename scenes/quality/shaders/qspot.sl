/* qspot: the shadow term of a spotlight, nothing else, for the shadow
   quality study (docs/shadow-quality.md). Cl = 1 - shadow(): no cone
   fall-off, no distance attenuation, so a surface that sums Cl shows
   exactly how much of the light's visibility the shadow lookup kept.
   shadowname "auto" makes umbra render the depth map inside the frame;
   "raytrace" traces the exact reference. The cone only bounds the lit
   region (the same in both), so points outside it get no Cl at all. */
light qspot(point from = point "shader" (0, 0, 0);
            point to = point "shader" (0, 0, 1);
            float coneangle = radians(30);
            string shadowname = "";
            float samples = 16, width = 1, bias = 0;)
{
    uniform vector A = (to - from) / length(to - from);
    illuminate(from, A, coneangle) {
        Cl = 1;
        if (shadowname != "")
            Cl = 1 - shadow(shadowname, Ps, "samples", samples, "width", width, "bias", bias);
    }
}
