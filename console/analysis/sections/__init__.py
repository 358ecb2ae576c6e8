"""Sections: the axle counter's safety logic, from detection events to section states, counts and the ledger."""
