"""Detection events: what every source feeds the section engine, one by one or as column blocks, and the queue
that orders them."""
