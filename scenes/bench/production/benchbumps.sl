/* benchbumps: ripples along the surface's own parameters, for the
   production benchmark's displaced patches. */
displacement benchbumps(float Km = 0.05; float frequency = 12)
{
    P += Km * sin(frequency * 2 * PI * s) * sin(frequency * 2 * PI * t) * normalize(N);
    N = calculatenormal(P);
}
