"""The ``ftrac-design`` command line (SPEC §5). One module per command."""
