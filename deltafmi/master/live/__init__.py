"""Live runs: pacing to the wall clock, live input sources (UDP, joystick), live output streams
(UDP, a plot window) and the exact replay of a live run from its results file."""

__all__: list[str] = []
