"""The stepping engine: the fmpy master loop, one FMU instance, events, the row stream."""
