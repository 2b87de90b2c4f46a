surface break_outside_loop()
{
    if (s > 0.5)
        break;
    Ci = 1;
}
