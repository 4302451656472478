"""The pipeline stages' commands: each parses its arguments and calls one library function (see ``cli.COMMANDS``)."""
