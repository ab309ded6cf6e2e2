"""State and parameter estimation from joint angles and motor torques (numpy only, no FMI).

- :mod:`.kalman`: extended-Kalman-filter algebra (transition matrix, Joseph update, white
  acceleration noise);
- :mod:`.delta_process`: the delta robot's stabilised DAE as a process model in joint
  coordinates with the loop closures (exact Jacobians, tangent basis, propagation);
- :mod:`.delta_process_kernels`: the same process model as plain-float kernels for a filter's
  sample (a Runge-Kutta period with its Jacobian, the projection, the wrist kinematics), which a
  component may hand the filter compiled;
- :mod:`.contact_ekf`: the contact estimator: the wrist (contact) force as a random walk and the
  surface height as a constant tied to it by the contact law, from the servo angles and torques;
- :mod:`.wrist_process`: the 6-DOF delta + wrist plant as a process model in its six coordinates;
- :mod:`.peg_contact`: the peg-in-hole contact law as a measurement of the hole, and a locator;
- :mod:`.peg_ekf`: the peg estimator: the contact wrench on the peg and the hole's position and
  tilt, from the servo and wrist angles and torques (import these three explicitly: they load
  the 6-DOF plant and the peg, which the delta's ContactEstimator FMU does not need).
"""
from .contact_ekf import ContactEKF, ContactEKFSettings, ContactEstimate
from .delta_process import process_jacobian, propagate, tangent_basis, wrist_jacobians
from .kalman import joseph_update, transition_matrix, white_acceleration_noise

__all__ = ["ContactEKF", "ContactEKFSettings", "ContactEstimate", "process_jacobian", "propagate",
           "tangent_basis", "wrist_jacobians", "joseph_update", "transition_matrix",
           "white_acceleration_noise"]
