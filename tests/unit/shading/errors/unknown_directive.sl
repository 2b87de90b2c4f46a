#frobnicate 3
surface unknown_directive()
{
    Ci = 1;
}
