"""Multi-mode (FREE / COLLISION / CONTACT) contact for Lagrangian systems, as in the seed talk.

:mod:`.system` is the mode machine (:class:`ContactSystem` over a :class:`LagrangianModel`),
:mod:`.collision_law` the compliant collision law of the COLLISION mode and its calibration,
:mod:`.material` a compliant contact in force units (stiffness, damping, restitution); the
tests drive it with a reference driver of FMI Model-Exchange event semantics (tests/hybrid_sim.py). The derivation is
in docs/contact.md; models built on it are in :mod:`deltafmi.physics.contact_problems` and
:mod:`deltafmi.physics.delta`.
"""
from .collision_law import CollisionLaw, calibrate
from .material import CompliantMaterial
from .system import ContactSystem, LagrangianModel, Mode

__all__ = ["CollisionLaw", "calibrate", "CompliantMaterial", "ContactSystem", "LagrangianModel", "Mode"]
