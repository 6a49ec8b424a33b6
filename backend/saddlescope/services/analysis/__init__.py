"""Analysing a ride: a bundle of clips end to end, a motion-capture file, the thesis's validation clips."""
