/* background: puts a colour behind the image, in every pixel by as much as
   nothing covers it (alpha), and makes the image opaque.

   Both names other RenderMan renderers give the colour are accepted:
   "bgcolor" (Aqsis, BMRT) and "background" (the name the RI Spec's
   depthcue and fog use for the same colour). Given both, they multiply. */
imager background(color bgcolor = 1; color background = 1;)
{
    Ci += (1 - alpha) * bgcolor * background;
    Oi = 1;
    alpha = 1;
}
