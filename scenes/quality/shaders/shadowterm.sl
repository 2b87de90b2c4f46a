/* shadowterm: the light reaching each point, without any cosine or
   colour: Ci = sum of Cl over the lights on the front hemisphere of the
   camera-facing normal. With qspot/qdistant each pixel is the shadow term
   in [0, 1]. Points facing away from the light get nothing, as the
   illumination model decides it (Wang & Molnar's "second surface is in
   shadow regardless of the depth comparison"). */
surface shadowterm()
{
    normal Nf = faceforward(normalize(N), I);
    color C = 0;
    illuminance(P, Nf, PI / 2) {
        C += Cl;
    }
    Oi = 1;
    Ci = C;
}
