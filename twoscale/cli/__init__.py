"""Command line: ``twoscale <subcommand> ...`` (see :mod:`twoscale.cli.main`)."""
