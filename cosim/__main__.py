"""``python -m cosim ...``: the ``auv-cosim`` command, for a Python whose scripts folder
is not on PATH (``python -m cosim run bs-3``)."""

import sys

from cosim.cli import main

sys.exit(main())
