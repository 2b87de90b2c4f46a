/* shadowdistant: distantlight attenuated by a depth-map shadow. */
light shadowdistant(float intensity = 1; color lightcolor = 1;
                    point from = point "shader" (0, 0, 0);
                    point to = point "shader" (0, 0, 1);
                    string shadowname = "";
                    float samples = 16, width = 1, blur = 0, bias = 0, bias0 = 0, bias1 = 0;)
{
    solar(to - from, 0.0) {
        Cl = intensity * lightcolor;
        if (shadowname != "")
            Cl *= 1 - shadow(shadowname, Ps, "samples", samples, "width", width, "blur", blur,
                             "bias", bias, "bias0", bias0, "bias1", bias1);
    }
}
