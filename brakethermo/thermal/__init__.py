"""Disc datasheet, 1D finite-element disc model, braking power and h(V) law."""
