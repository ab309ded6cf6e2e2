"""``python -m deltafmi.apps.scope``: the scope command, as a ``plot:`` stream starts it."""
from .command import scope

scope.main(prog_name="python -m deltafmi.apps.scope")
