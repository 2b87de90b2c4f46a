float halve(float x) { float y = x / 2; }

surface missing_return()
{
    Ci = halve(s);
}
