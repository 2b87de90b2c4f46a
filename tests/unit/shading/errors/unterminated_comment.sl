surface unterminated_comment()
{
    /* this comment never ends
    Ci = 1;
}
