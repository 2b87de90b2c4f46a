// A varying early return (a mask frame and a break out of it) and a
// function that returns another function's call (no frame: one return).
float ramp(float x)
{
    if (x > 0.5)
        return 1;
    return 2 * x;
}

float twice(float x) { return ramp(x) * 2; }

surface early_return()
{
    Ci = twice(s);
}
