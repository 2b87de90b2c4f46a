/* constant: the surface colour, unlit (RI spec 3.2, appendix A). */
surface constant()
{
    Oi = Os;
    Ci = Os * Cs;
}
