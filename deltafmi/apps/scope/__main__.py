"""``python -m deltafmi.apps.scope``: ``deltafmi scope``, as a ``plot:`` stream starts it (through the
command group, so that its errors end in one line and their exit codes)."""
import sys

from deltafmi.apps.cli import main

main(["scope", *sys.argv[1:]], prog_name="python -m deltafmi.apps.scope")
