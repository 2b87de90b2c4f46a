surface missing_semicolon()
{
    float a = 1
    Ci = a;
}
