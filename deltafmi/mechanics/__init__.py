"""Numerical mechanics with no FMI inside: delta robot kinematics and dynamics, control-side
math, trajectories and multi-mode contact. Bundled into FMUs, so it imports only numpy/scipy."""
