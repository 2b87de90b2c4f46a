surface assign_to_readonly()
{
    du = 2;
}
