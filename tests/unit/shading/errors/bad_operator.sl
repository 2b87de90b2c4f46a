surface bad_operator()
{
    string a = "x";
    Ci = a * 2;
}
