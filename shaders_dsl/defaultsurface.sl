/* defaultsurface: used when no surface shader is given; lit from the eye. */
surface defaultsurface(float Kd = .8, Ka = .2;)
{
    float d = normalize(I) . normalize(N);
    Ci = Os * Cs * (Ka + Kd * d * d);
    Oi = Os;
}
