"""``python -m cosim ...``: the ``auv-cosim`` command, for a Python whose scripts folder
is not on PATH (``python -m cosim run bs-3``)."""

import sys

from cosim.cli import main

if __name__ == "__main__":  # imported (a test importing every module), it runs nothing
    sys.exit(main())
