float twice(float x) { return 2 * x; }

surface wrong_argument_count()
{
    Ci = twice(s, t);
}
