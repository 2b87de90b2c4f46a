surface tint(color tint = color(1, 0.5, 0.25))
{
    Ci = tint * Cs * 2;
    Oi = Os;
}
