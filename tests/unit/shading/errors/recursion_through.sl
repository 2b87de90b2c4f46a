float odd(float n) { return n < 1 ? 0 : even(n - 1); }
float even(float n) { return n < 1 ? 1 : odd(n - 1); }

surface recursion_through()
{
    Ci = even(floor(s * 4));
}
