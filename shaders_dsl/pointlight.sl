/* pointlight: light from a point, falling off with the squared distance (RI spec 3.2). */
light pointlight(float intensity = 1; color lightcolor = 1;
                 point from = point "shader" (0, 0, 0);)
{
    illuminate(from)
        Cl = intensity * lightcolor / (L . L);
}
