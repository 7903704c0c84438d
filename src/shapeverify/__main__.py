"""``python -m shapeverify``: the ``shapeverify`` command."""

from shapeverify.cli_start import run

run()
