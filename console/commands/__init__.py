"""One module per trackside command; console.cli assembles them."""
