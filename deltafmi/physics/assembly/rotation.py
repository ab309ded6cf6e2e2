"""Rotation algebra in the kernel float subset: 3x3 matrices as 9 floats, row-major.

What the assembly controller needs per sample, with no numpy (deltafmi/builder/codegen translates
these to C): products, the rotation vector of a rotation (the logarithm map, orientation errors),
Rodrigues' formula (its inverse, for references) and orientation references with their rates.

Orientation references are rotation vectors phi(t) about a base rotation R0, R_ref = exp([phi]x) R0,
with the world angular velocity and acceleration (the left Jacobian of SO(3); Chirikjian,
Stochastic Models, Information Theory, and Lie Groups, vol. 2, 2011, sec. 10.6)

    omega = J_l phid = phid + a (phi x phid) + b phi x (phi x phid),
    alpha = J_l phidd + a' thd (phi x phid) + b' thd phi x (phi x phid) + b phid x (phi x phid),
    a = (1 - cos th) / th^2,  b = (th - sin th) / th^3,  th = |phi|,  thd = phi . phid / th,

(series a = 1/2 - th^2/24, b = 1/6 - th^2/120, a' = -th/12, b' = -th/60 below th = 1e-3, their
truncation errors below 1e-13).

Logarithm map (Murray, Li & Sastry, A Mathematical Introduction to Robotic Manipulation, 1994,
sec. 2.2): for R = exp([phi]x) with angle theta = |phi| in [0, pi),

    cos theta = (tr R - 1) / 2,   v = (R32 - R23, R13 - R31, R21 - R12) / 2 = sin theta n,
    phi = theta n = atan2(|v|, cos theta) / |v| * v,

and theta / sin theta -> 1 + theta^2 / 6 as |v| -> 0 (used below |v| < 1e-8, where the next
term, 7 theta^4 / 360, is below 1e-32 relative). At theta = pi (v = 0) the axis is not
defined by v: the controller's orientation errors stay far below that (module law).
"""

from __future__ import annotations

import math

from ..wrist.kernels import cross

__all__ = ["F3", "F9", "TOOL_DOWN", "matmul", "transpose", "apply", "apply_t", "rotation_vector",
           "rotation_from_vector", "cross", "orientation_reference"]

F3 = tuple[float, float, float]
F9 = tuple[float, float, float, float, float, float, float, float, float]

#: the tool frame at wrist angles 0: tool z (the peg axis) points down (wrist.params.TOOL_FLIP)
TOOL_DOWN: F9 = (1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0)


def matmul(a: F9, b: F9) -> F9:
    """a b."""
    return (a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
            a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
            a[3] * b[0] + a[4] * b[3] + a[5] * b[6], a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
            a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
            a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
            a[6] * b[2] + a[7] * b[5] + a[8] * b[8])


def transpose(a: F9) -> F9:
    """a^T."""
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


def apply(a: F9, v: F3) -> F3:
    """a v."""
    return (a[0] * v[0] + a[1] * v[1] + a[2] * v[2], a[3] * v[0] + a[4] * v[1] + a[5] * v[2],
            a[6] * v[0] + a[7] * v[1] + a[8] * v[2])


def apply_t(a: F9, v: F3) -> F3:
    """a^T v."""
    return (a[0] * v[0] + a[3] * v[1] + a[6] * v[2], a[1] * v[0] + a[4] * v[1] + a[7] * v[2],
            a[2] * v[0] + a[5] * v[1] + a[8] * v[2])


def rotation_vector(r: F9) -> F3:
    """phi with R = exp([phi]x), |phi| < pi (module docstring): the logarithm map."""
    vx = 0.5 * (r[7] - r[5])
    vy = 0.5 * (r[2] - r[6])
    vz = 0.5 * (r[3] - r[1])
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    c = 0.5 * (r[0] + r[4] + r[8] - 1.0)
    if s < 1e-8:
        k = 1.0 + s * s / 6.0   # theta / sin theta, theta = s to this order
    else:
        k = math.atan2(s, c) / s
    return k * vx, k * vy, k * vz


def rotation_from_vector(phi: F3) -> F9:
    """exp([phi]x) by Rodrigues' formula: 1 + sin t [n]x + (1 - cos t) [n]x^2, t = |phi|."""
    x, y, z = phi
    t = math.sqrt(x * x + y * y + z * z)
    if t < 1e-12:
        return (1.0, -z, y, z, 1.0, -x, -y, x, 1.0)
    nx, ny, nz = x / t, y / t, z / t
    s, c = math.sin(t), 1.0 - math.cos(t)
    return (1.0 - c * (ny * ny + nz * nz), c * nx * ny - s * nz, c * nx * nz + s * ny,
            c * nx * ny + s * nz, 1.0 - c * (nx * nx + nz * nz), c * ny * nz - s * nx,
            c * nx * nz - s * ny, c * ny * nz + s * nx, 1.0 - c * (nx * nx + ny * ny))


def orientation_reference(phi: F3, phid: F3, phidd: F3, base: F9) -> tuple[F9, F3, F3]:
    """(R_ref, omega_ref, alpha_ref) for R_ref = exp([phi]x) base (module docstring), world frame."""
    th = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    pxd = cross(phi, phid)
    ppxd = cross(phi, pxd)
    dxp = cross(phid, pxd)
    if th < 1e-3:
        a, b, ap, bp = 0.5 - th * th / 24.0, 1.0 / 6.0 - th * th / 120.0, -th / 12.0, -th / 60.0
    else:
        c, s = math.cos(th), math.sin(th)
        t2 = th * th
        a, b = (1.0 - c) / t2, (th - s) / (t2 * th)
        ap = (th * s - 2.0 * (1.0 - c)) / (t2 * th)
        bp = (1.0 - c) / (t2 * th) - 3.0 * (th - s) / (t2 * t2)
    thd = (phi[0] * phid[0] + phi[1] * phid[1] + phi[2] * phid[2]) / th if th > 0.0 else 0.0
    omega = (phid[0] + a * pxd[0] + b * ppxd[0], phid[1] + a * pxd[1] + b * ppxd[1], phid[2] + a * pxd[2] + b * ppxd[2])
    pxdd = cross(phi, phidd)
    ppxdd = cross(phi, pxdd)
    ka, kb = ap * thd, bp * thd
    alpha = (phidd[0] + a * pxdd[0] + b * ppxdd[0] + ka * pxd[0] + kb * ppxd[0] + b * dxp[0],
             phidd[1] + a * pxdd[1] + b * ppxdd[1] + ka * pxd[1] + kb * ppxd[1] + b * dxp[1],
             phidd[2] + a * pxdd[2] + b * ppxdd[2] + ka * pxd[2] + kb * ppxd[2] + b * dxp[2])
    return matmul(rotation_from_vector(phi), base), omega, alpha
