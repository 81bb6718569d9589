"""``python -m edgetruth`` = the ``edgetruth`` command."""
import sys

from edgetruth.cli import main

sys.exit(main())
