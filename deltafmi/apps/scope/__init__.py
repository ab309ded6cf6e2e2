"""The live plot window (``deltafmi scope``, and what a scenario's ``plot:`` stream starts):
:mod:`.window` draws, :mod:`.data` holds the rolling buffers, :mod:`.command` is the command."""

__all__: list[str] = []
