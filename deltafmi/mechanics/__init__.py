"""Numerical mechanics with no FMI inside. Bundled into FMUs: what an FMU reaches imports only numpy.

- :mod:`.delta`: the delta robot (parameters, kinematics, stabilised DAE dynamics, control law
  and sampled controller, wrist trajectories);
- :mod:`.wrist`: a 3-DOF direct-drive spherical wrist with its tool (kinematics, joint-space
  dynamics, gimbal singularity, its load on the delta's plate);
- :mod:`.contact`: the multi-mode FREE / COLLISION / CONTACT framework and its collision law;
- :mod:`.friction`: Coulomb friction with stick and slip as contact modes, viscous terms, and
  the peg-in-hole wedging and jamming conditions;
- :mod:`.examples`: the talk's contact examples built on it (bouncing ball, Newton's cradle,
  box on a table).
"""
