surface unknown_function()
{
    Ci = frobnicate(s, t);
}
