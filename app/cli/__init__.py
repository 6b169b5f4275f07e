"""The command line: ``handmocap SUBCOMMAND`` (see :mod:`app.cli.main`)."""
