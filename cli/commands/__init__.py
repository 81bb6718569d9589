"""CLI subcommands: each module here defines ``register(subparsers)``; ``edgetruth.cli`` finds them all.

A subcommand's handler takes the parsed ``argparse.Namespace`` and returns an exit
code (0 on success).  Raise ``edgetruth.errors.InputError`` for bad input, and check
every output path before long work starts (``edgetruth.fileio``).
"""
