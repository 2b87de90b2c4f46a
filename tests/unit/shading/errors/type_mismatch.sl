surface type_mismatch()
{
    color c = point(1, 2, 3);
    Ci = c;
}
