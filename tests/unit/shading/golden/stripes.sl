surface stripes(float freq = 4)
{
    float k;
    color c = 0;
    for (k = 0; k < 3; k += 1) {
        if (mod(floor(s * freq) + k, 2) == 0)
            continue;
        c += color(k, 1, 0);
    }
    Ci = c;
}
