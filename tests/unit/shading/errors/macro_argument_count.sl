#define MIX(a, b) ((a) + (b))
surface macro_argument_count()
{
    Ci = MIX(s);
}
