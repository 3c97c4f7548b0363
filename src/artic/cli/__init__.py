"""The `artic` command line: one thin Typer module per subcommand."""
