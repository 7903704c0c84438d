"""``python -m shapeverify``: the ``shapeverify`` command."""

import sys

from shapeverify.cli_start import main

sys.exit(main())
