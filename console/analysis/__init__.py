"""Pure domain logic: no file I/O, no printing, no widgets."""
