"""Peg-in-hole contact mechanics (issue 27, item 3): a cylindrical peg held by the wrist, a chamfered
hole in a fixture (numpy-free kernels, no FMI).

:mod:`.params` the hole, peg and contact-law parameters; :mod:`.contact` the contact wrench on the
peg (:func:`peg_wrench`: penalty normal forces at 32 rim points and the hole's two rounded edges,
regularised Coulomb friction, insertion diagnostics); :mod:`.rigid_peg` a free 6-DOF rigid peg
(the reference the tests integrate with scipy); :mod:`.plant` the kernels of the DeltaWristPeg FMU
(the delta + wrist plant of deltafmi.physics.delta_wrist with the contact wrench on its tool;
import it explicitly, it loads the 6-DOF plant). Wedging and jamming in closed form: deltafmi.physics.friction.peg.
"""
from .contact import RIM_POINTS, PegWrench, hole_rotation, peg_wrench
from .params import Hole, Peg, PegContact, validate
from .rigid_peg import RigidPeg

__all__ = ["Hole", "Peg", "PegContact", "validate", "RIM_POINTS", "PegWrench", "peg_wrench", "hole_rotation",
           "RigidPeg"]
