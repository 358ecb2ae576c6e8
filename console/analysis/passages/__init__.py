"""Passages: a train's run over one counting head, from parsed records, in bounded memory; status-only runs,
overlaps, JSON text."""
