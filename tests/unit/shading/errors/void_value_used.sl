void paint(color c) { Ci = c; }

surface void_value_used()
{
    Oi = paint(Cs);
}
