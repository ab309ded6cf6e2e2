"""Numerical mechanics with no FMI inside. Bundled into FMUs: what an FMU reaches imports only numpy.

- :mod:`.delta`: the delta robot (parameters, kinematics, stabilised DAE dynamics, control law
  and sampled controller, wrist trajectories);
- :mod:`.wrist`: a 3-DOF direct-drive spherical wrist with its tool (kinematics, joint-space
  dynamics, gimbal singularity, its load on the delta's plate), and float kernels of its dynamics
  in :mod:`.wrist.kernels`;
- :mod:`.delta_wrist`: the 6-DOF plant (delta + wrist on its plate) as float kernels: state
  derivative, outputs, projection, start state, holding torques;
- :mod:`.contact`: the multi-mode FREE / COLLISION / CONTACT framework and its collision law;
- :mod:`.friction`: Coulomb friction with stick and slip as contact modes, viscous terms, and
  the peg-in-hole wedging and jamming conditions;
- :mod:`.peg`: peg-in-hole contact (a chamfered hole with rounded edges, 32 rim points and two
  edge contacts, regularised Coulomb friction), a free rigid peg, and the DeltaWristPeg kernels;
- :mod:`.assembly`: the assembly controller (6-D impedance control of the delta and the wrist)
  and its insertion program;
- :mod:`.estimation`: extended Kalman filters of the contact (force, surface, hole) from joint
  angles and motor torques;
- :mod:`.examples`: the talk's contact examples built on it (bouncing ball, Newton's cradle,
  box on a table).
"""

__all__: list[str] = []
