"""Coulomb friction with stick and slip as contact modes, plus viscous terms.

:mod:`.law` the laws of one contact's modes (STICK, SLIP+, SLIP-) and the regularised law for
comparison; :mod:`.system` the mode machine over a Lagrangian model with sliding contacts
(:class:`FrictionSystem`, FMU-shaped like :mod:`deltafmi.physics.contact`); :mod:`.planar_block`
the block the tests check against closed forms (on an incline, the stick-slip oscillator);
:mod:`.peg` the peg-in-hole wedging and jamming conditions (Whitney 1982), checked by the
quasi-static model of :mod:`.peg_statics`.
"""
from .law import SEPARATED, SLIP_NEGATIVE, SLIP_POSITIVE, STICK, FrictionParams
from .system import FrictionModel, FrictionSystem, Transition

__all__ = ["FrictionParams", "FrictionModel", "FrictionSystem", "Transition",
           "SEPARATED", "STICK", "SLIP_POSITIVE", "SLIP_NEGATIVE"]
