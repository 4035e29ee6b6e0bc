"""Command-line tools of ``rigid-body-sim``: one module per subcommand (see cli.TOOLS)."""
