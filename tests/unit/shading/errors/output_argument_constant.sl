void setit(output float x) { x = 1; }

surface output_argument_constant()
{
    setit(3);
}
