#ifdef FOO
surface unterminated_ifdef()
{
    Ci = 1;
}
