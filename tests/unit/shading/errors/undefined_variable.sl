surface undefined_variable()
{
    Ci = foo * Cs;
}
