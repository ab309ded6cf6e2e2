"""Generic linear model-predictive control: no robot, no FMI.

``models`` turns a continuous linearization (``deltafmi linearize -o``) into discrete affine stage
models: reduction to the controllable subspace, zero-order-hold discretisation, closing a
spring-damper between outputs and inputs (a compliant contact as a mode). ``mpc`` is the
constrained linear MPC over such stages, solved by OSQP or (``active_set``) DAQP; ``lqr`` the
finite-horizon Riccati recursion it reduces to without constraints. ``contact_mpc`` assembles a hybrid MPC of a
mechanical system pressing on a plane (free and contact modes along the horizon); ``model_file``
reads a linearization file with numpy alone (what an FMU can carry). ``reduction`` lifts a
closed loop's one-step linearization to an MPC's sample and balances and truncates it;
``insertion`` is the MPC that plans an impedance controller's reference for a peg insertion
(:mod:`deltafmi.apps.insertion_mpc_model` writes its model).
"""
from .lqr import finite_horizon_lqr
from .models import AffineStage, controllable_subspace, spring_contact, zoh
from .mpc import LinearMPC, MpcSolution

__all__ = ["AffineStage", "LinearMPC", "MpcSolution", "controllable_subspace", "finite_horizon_lqr",
           "spring_contact", "zoh"]
