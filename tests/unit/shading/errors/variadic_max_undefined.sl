volume variadic_max_undefined(color background = 0;)
{
    Ci = max(Ci, bacgkround, 0.5);
}
