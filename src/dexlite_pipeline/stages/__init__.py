"""Command-line stages: thin argument parsing around library calls (see ``cli.COMMANDS``)."""
