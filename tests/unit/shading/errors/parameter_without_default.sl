surface parameter_without_default(float Kd;)
{
    Ci = Kd;
}
