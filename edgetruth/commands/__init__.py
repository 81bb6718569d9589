"""CLI subcommands: each module here defines ``register(subparsers)``; cli.py finds them all.

A subcommand's handler takes the parsed ``argparse.Namespace`` and returns an
exit code (0 on success).  Raise ``edgetruth.errors.InputError`` for bad input.
"""
