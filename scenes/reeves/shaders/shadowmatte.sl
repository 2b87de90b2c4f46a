/* shadowmatte: shows only the light arriving at each point, with no
   diffuse or specular term (Reeves et al. 1987 Figure 6, "shadow
   component"). With reevesspot's shadowonly = 1 the image is white where lit
   and black where shadowed. */
surface shadowmatte(float Kd = 1;)
{
    color C = 0;
    illuminance(P) {
        C += Cl;
    }
    Oi = Os;
    Ci = Os * Kd * C;
}
