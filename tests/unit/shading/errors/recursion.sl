float f(float x) { return f(x - 1); }

surface recursion()
{
    Ci = f(s);
}
