"""Derive one delta-robot arm's Lagrangian dynamics with sympy and verify the shipped numpy code.

Run:  python tools/derive_delta_dynamics.py      (needs sympy; a few seconds)

Builds the arm's kinetic and potential energy from body positions (upper arm about the servo
axis, forearm as a thin rod integrated along its length, one third of the plate as a point mass
at the arm end), forms m(q), c(q, v) = mdot v - dT/dq and g(q) = dV/dq, the wrist map psi, its
Jacobian and velocity-product term, prints them, proves them equal to the closed forms written in
deltafmi/physics/delta/dynamics.py's docstring, and checks deltafmi.physics.delta numerically
at random states. Exits non-zero on any mismatch.
"""

from __future__ import annotations

import sys

import numpy as np
import sympy as sp

from deltafmi.physics import delta


def derive() -> dict[str, sp.Matrix]:
    """Symbolic m, c, g, psi, J, Jdot v and the energies of one arm."""
    q1, q2, q3, v1, v2, v3 = sp.symbols("q1 q2 q3 v1 v2 v3", real=True)
    l0, l1, l2, l3, m1, r1, J1, Jm, m2, mpa, g, s = sp.symbols(
        "l0 l1 l2 l3 m1 r1 J1 Jm m2 mpa g sigma", positive=True)
    q, v = sp.Matrix([q1, q2, q3]), sp.Matrix([v1, v2, v3])

    def ddt(expr):
        return (expr.jacobian(q) if isinstance(expr, sp.MatrixBase) else
                sp.Matrix([expr]).jacobian(q)) * v

    elbow = sp.Matrix([0, l0 + l1 * sp.cos(q1), l1 * sp.sin(q1)])
    u = sp.Matrix([sp.sin(q2) * sp.sin(q3), sp.cos(q2), sp.sin(q2) * sp.cos(q3)])
    arm_end = elbow + l2 * u
    psi = arm_end - sp.Matrix([0, l3, 0])

    rod_point = elbow + s * u  # s in [0, l2] along the forearm
    rod_vel = ddt(rod_point)
    T_rod = sp.integrate((m2 / l2) * rod_vel.dot(rod_vel) / 2, (s, 0, l2))
    V_rod = sp.integrate((m2 / l2) * g * rod_point[2], (s, 0, l2))
    end_vel = ddt(arm_end)
    T = (J1 + Jm) * v1 ** 2 / 2 + T_rod + mpa * end_vel.dot(end_vel) / 2
    V = m1 * g * r1 * sp.sin(q1) + V_rod + mpa * g * arm_end[2]

    M = sp.hessian(T, v).applyfunc(sp.simplify)
    Mdot_v = sum((M.diff(qk) * vk for qk, vk in zip(q, v)), sp.zeros(3, 3)) * v
    C = (Mdot_v - sp.Matrix([T]).jacobian(q).T).applyfunc(sp.simplify)
    G = sp.Matrix([V]).jacobian(q).T.applyfunc(sp.simplify)
    J = psi.jacobian(q)
    bias = sum((J.diff(qk) * vk for qk, vk in zip(q, v)), sp.zeros(3, 3)) * v  # Jdot v
    syms = dict(q1=q1, q2=q2, q3=q3, v1=v1, v2=v2, v3=v3, l0=l0, l1=l1, l2=l2, l3=l3, m1=m1,
                r1=r1, J1=J1, Jm=Jm, m2=m2, mpa=mpa, g=g)
    return dict(M=M, C=C, G=G, psi=psi, J=J, bias=bias.applyfunc(sp.simplify),
                T=sp.Matrix([T]), V=sp.Matrix([V]), syms=syms)


def closed_forms(S: dict) -> dict[str, sp.Matrix]:
    """The closed forms as written in delta.dynamics' docstring, transcribed to sympy."""
    q1, q2, q3, v1, v2, v3 = (S[k] for k in ("q1", "q2", "q3", "v1", "v2", "v3"))
    l1, l2, m1, r1, J1, Jm, m2, mpa, g = (S[k] for k in
                                          ("l1", "l2", "m1", "r1", "J1", "Jm", "m2", "mpa", "g"))
    s1, c1, s2, c2, s3, c3 = (sp.sin(q1), sp.cos(q1), sp.sin(q2), sp.cos(q2), sp.sin(q3),
                              sp.cos(q3))
    a = J1 + Jm + (m2 + mpa) * l1 ** 2
    b = (m2 / 2 + mpa) * l1 * l2
    beta = (m2 / 3 + mpa) * l2 ** 2
    M = sp.Matrix([[a, b * (s1 * s2 + c1 * c2 * c3), -b * c1 * s2 * s3],
                   [b * (s1 * s2 + c1 * c2 * c3), beta, 0],
                   [-b * c1 * s2 * s3, 0, beta * s2 ** 2]])
    C = sp.Matrix([
        b * ((s1 * c2 - c1 * s2 * c3) * v2 ** 2 - 2 * c1 * c2 * s3 * v2 * v3
             - c1 * s2 * c3 * v3 ** 2),
        b * (c1 * s2 - s1 * c2 * c3) * v1 ** 2 - beta * s2 * c2 * v3 ** 2,
        b * s1 * s2 * s3 * v1 ** 2 + 2 * beta * s2 * c2 * v2 * v3])
    G = sp.Matrix([g * (m1 * r1 + (m2 + mpa) * l1) * c1,
                   g * (m2 / 2 + mpa) * l2 * c2 * c3,
                   -g * (m2 / 2 + mpa) * l2 * s2 * s3])
    return dict(M=M, C=C, G=G)


def numeric_check(D: dict, rng: np.random.Generator) -> float:
    """Largest relative mismatch between the sympy model and deltafmi.physics.delta."""
    S = D["syms"]
    p = delta.DeltaParams(payload=1.3, damping=0.0)
    subs_p = {S["l0"]: p.l0, S["l1"]: p.l1, S["l2"]: p.l2, S["l3"]: p.l3, S["m1"]: p.m1,
              S["r1"]: p.r1, S["J1"]: p.J1, S["Jm"]: p.Jm, S["m2"]: p.m2,
              S["mpa"]: (p.mp + p.payload) / 3, S["g"]: p.g}
    names = ("q1", "q2", "q3", "v1", "v2", "v3")
    f = {k: sp.lambdify([S[n] for n in names], D[k].subs(subs_p), "numpy")
         for k in ("M", "C", "G", "psi", "J", "bias", "T", "V")}
    worst = 0.0
    for _ in range(20):
        q = np.concatenate([rng.uniform(-1.5, 0.5, 1), rng.uniform(-3.0, -0.2, 1),
                            rng.uniform(-1.2, 1.2, 1)])
        v = rng.normal(size=3)
        q9, v9 = np.tile(q, 3), np.tile(v, 3)
        args = (*q, *v)
        pairs = [
            (np.array(f["M"](*args), float), delta.mass_matrix(p, q9)[:3, :3]),
            (np.array(f["C"](*args), float).ravel(), delta.coriolis(p, q9, v9)[:3]),
            (np.array(f["G"](*args), float).ravel(), delta.gravity(p, q9)[:3]),
            (np.array(f["psi"](*args), float).ravel(), delta.arm_psi(p, q)),
            (np.array(f["J"](*args), float), delta.arm_jacobian(p, q)),
            (np.array(f["bias"](*args), float).ravel(), delta.arm_bias(p, q, v)),
            (3 * (float(np.squeeze(f["T"](*args))) + float(np.squeeze(f["V"](*args)))),
             delta.energy(p, q9, v9)),
        ]
        for ref, got in pairs:
            ref, got = np.asarray(ref, float), np.asarray(got, float)
            worst = max(worst, float(np.max(np.abs(ref - got)) / (1.0 + np.max(np.abs(ref)))))
    return worst


def main() -> int:
    D = derive()
    for k in ("psi", "J", "bias", "M", "C", "G"):
        mat = D[k]
        for i in range(mat.rows):
            for j in range(mat.cols):
                idx = f"[{i + 1}]" if mat.cols == 1 else f"[{i + 1},{j + 1}]"
                print(f"{k}{idx} = {sp.factor_terms(mat[i, j])}")
        print()
    ok = True
    for k, ref in closed_forms(D["syms"]).items():
        zero = (D[k] - ref).applyfunc(lambda e: sp.simplify(sp.expand_trig(e)))
        same = zero == sp.zeros(*ref.shape)
        ok &= same
        print(f"{k}: sympy derivation == docstring closed form: {same}")
    err = numeric_check(D, np.random.default_rng(1))
    print(f"numpy library vs sympy at 20 random states: max relative error {err:.2e}")
    ok &= err < 1e-12
    print("OK" if ok else "MISMATCH")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
