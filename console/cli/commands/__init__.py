"""One module per trackside command; console.cli.app assembles them."""
