"""``python -m deltafmi.apps COMMAND ...``: the ``deltafmi`` command without its console script (what a
``plot:`` stream runs to start ``scope``)."""
from deltafmi.apps.cli import main

main(prog_name="python -m deltafmi.apps")
