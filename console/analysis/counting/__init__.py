"""Counting axles: the wheel records of each head's two systems (and the sensors' own rules) to axles, direction
and speed."""
