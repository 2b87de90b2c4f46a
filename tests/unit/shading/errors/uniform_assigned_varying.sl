surface uniform_assigned_varying()
{
    uniform float x = 0;
    x = s * 2;
    Ci = x;
}
