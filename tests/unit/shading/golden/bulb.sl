light bulb(float intensity = 1)
{
    illuminate(point "shader" (0, 0, 0))
        Cl = intensity / (L . L);
}
