"""Numerical mechanics with no FMI inside. Bundled into FMUs: what an FMU reaches imports only numpy.

- :mod:`.delta`: the delta robot (parameters, kinematics, stabilised DAE dynamics, control law
  and sampled controller, wrist trajectories);
- :mod:`.contact`: the multi-mode FREE / COLLISION / CONTACT framework and its collision law;
- :mod:`.examples`: the talk's contact examples built on it (bouncing ball, Newton's cradle,
  box on a table).
"""
