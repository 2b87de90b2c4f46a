surface illuminate_in_surface()
{
    illuminate(P)
        Ci = 1;
}
