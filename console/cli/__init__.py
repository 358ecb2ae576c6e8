"""The `trackside` command line: the Typer app (:mod:`console.cli.app`), the option types, one module per command."""
