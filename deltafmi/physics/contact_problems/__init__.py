"""The contact examples of the seed talk on :mod:`deltafmi.physics.contact`: the bouncing ball
(the talk's Modelica model and a restitution-law ball), Newton's cradle, a box dropped on a table."""

__all__: list[str] = []
