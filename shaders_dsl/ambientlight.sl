/* ambientlight: non-directional light, read by ambient() (RI spec 3.2). */
light ambientlight(float intensity = 1; color lightcolor = 1;)
{
    Cl = intensity * lightcolor;
}
