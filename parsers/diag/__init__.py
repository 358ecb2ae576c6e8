"""Diagnostic records of the axle counters: fields, labels, the registry of one read, the reader."""
