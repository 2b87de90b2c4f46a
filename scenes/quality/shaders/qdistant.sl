/* qdistant: the shadow term of a distant light (Cl = 1 - shadow()), the
   directional counterpart of qspot for the study's orthographic maps. */
light qdistant(point from = point "shader" (0, 0, 0);
               point to = point "shader" (0, 0, 1);
               string shadowname = "";
               float samples = 16, width = 1, bias = 0;)
{
    solar(to - from, 0.0) {
        Cl = 1;
        if (shadowname != "")
            Cl = 1 - shadow(shadowname, Ps, "samples", samples, "width", width, "bias", bias);
    }
}
