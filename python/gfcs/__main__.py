"""``python -m gfcs``: the ``gfcs`` command (:func:`gfcs.cli.main`) for environments without its script
on PATH."""

import sys

from gfcs.cli import main

if __name__ == "__main__":
    sys.exit(main())
