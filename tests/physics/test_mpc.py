"""deltafmi.physics.control: the linear MPC against independent solutions (Riccati, SLSQP, closed forms)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from scipy.optimize import minimize

from deltafmi.physics.control import LinearMPC, controllable_subspace, finite_horizon_lqr, spring_contact, zoh
from deltafmi.physics.control.active_set import DenseActiveSetQP
from deltafmi.physics.control.contact_mpc import PlaneContactMpc, PressTask
from deltafmi.master.linearize.linear_model import LinearModel


def random_system(seed: int, nx: int = 4, nu: int = 2, ny: int = 3):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(nx, nx)) * 0.5
    return rng, A, rng.normal(size=(nx, nu)), rng.normal(size=(ny, nx)), 0.3 * rng.normal(size=(ny, nu))


def test_zoh_of_a_double_integrator_with_a_constant_force_is_the_closed_form():
    """x'' = u + a: Ad = [[1, T], [0, 1]], Bd = [T^2/2, T], ed = a [T^2/2, T] (exact)."""
    T, a = 0.01, -9.81
    stage = zoh(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), T, e=np.array([0.0, a]))
    np.testing.assert_allclose(stage.A, [[1.0, T], [0.0, 1.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(stage.B[:, 0], [T * T / 2, T], rtol=1e-13)
    np.testing.assert_allclose(stage.e, [a * T * T / 2, a * T], rtol=1e-13)


def test_controllable_subspace_drops_modes_no_input_reaches():
    """A block-diagonal system whose second block has no input: the basis spans the first block
    exactly and is A-invariant."""
    rng, A1, B1, _, _ = random_system(3, nx=3, nu=1)
    A = scipy.linalg.block_diag(A1, -np.diag([5.0, 6.0]))
    B = np.vstack([B1, np.zeros((2, 1))])
    basis = controllable_subspace(A, B)
    assert basis.shape == (5, 3)
    np.testing.assert_allclose(basis[3:], 0.0, atol=1e-12)
    residual = A @ basis - basis @ (basis.T @ A @ basis)
    assert np.abs(residual).max() < 1e-12


def test_spring_contact_on_a_free_mass_is_a_mass_spring_damper():
    """m x'' = f with f = -K (x + gap0) - D x': poles the roots of m s^2 + D s + K; rest at x = -gap0."""
    m, K, D, gap0 = 17.0, 2e5, 2e3, 0.001
    A, Bf = np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0 / m]])
    Ac, ec, H, h = spring_contact(A, Bf, np.array([1.0]), np.array([[1.0, 0.0]]), np.array([[0.0, 1.0]]),
                                  gap0, K, D)
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(Ac)), np.sort_complex(np.roots([m, D, K])),
                               rtol=1e-12)
    rest = np.linalg.solve(Ac, -ec)
    np.testing.assert_allclose(rest, [-gap0, 0.0], atol=1e-15)
    assert H @ rest + h == pytest.approx(0.0, abs=1e-9)  # at rest the spring is just unloaded


@pytest.mark.parametrize("seed", [0, 1])
def test_unconstrained_mpc_is_the_finite_horizon_lqr(seed):
    """No bounds: the MPC's first move is -K_0 x with K_0 from the Riccati recursion, the cost
    carrying the output cross term (S = C'QD). OSQP stops at residuals below 1e-10; the QP's
    Hessian has a condition number of a few 1e3 here, so the gain is right to ~1e-7 of its size:
    asserted to 1e-6 (relative to the largest gain)."""
    rng, A, B, C, D = random_system(seed)
    N, Q, R, Q_N = 20, np.diag([1.0, 2.0, 3.0]), 0.5 * np.eye(2), np.diag([4.0, 1.0, 2.0])
    stage = zoh(A, B, 0.1)
    mpc = LinearMPC(stage, C, D, np.zeros(3), Q, R, N, Q_N=Q_N, eps=1e-10)
    gains = finite_horizon_lqr(stage.A, stage.B, C.T @ Q @ C, C.T @ Q @ D, D.T @ Q @ D + R, C.T @ Q_N @ C, N)
    mpc_gain = -np.column_stack([mpc.solve(e, np.zeros(3)).u0 for e in np.eye(4)])
    assert np.abs(mpc_gain - gains[0]).max() <= 1e-6 * np.abs(gains[0]).max()


def _reference_first_move(stages, x0, C, D, g, Q, R, r, u_lo, u_hi, H, h, hi):
    """The same problem written independently: the inputs as the only unknowns, the states by
    stepping the stages, the output limits as hard inequalities, solved by SLSQP."""
    N, nu = len(stages), stages[0].B.shape[1]

    def states(U):
        xs, x = [x0], x0
        for k, s in enumerate(stages):
            x = s.A @ x + s.B @ U[k * nu:(k + 1) * nu] + s.e
            xs.append(x)
        return xs

    def cost(U):
        xs, total = states(U), 0.0
        for k in range(N):
            z = C @ xs[k] + D @ U[k * nu:(k + 1) * nu] + g - r
            total += 0.5 * z @ Q @ z + 0.5 * U[k * nu:(k + 1) * nu] @ R @ U[k * nu:(k + 1) * nu]
        z = C @ xs[N] + g - r
        return total + 0.5 * z @ Q @ z

    limits = {"type": "ineq", "fun": lambda U: np.concatenate([hi - (H @ x + h) for x in states(U)[1:]])}
    result = minimize(cost, np.zeros(N * nu), method="SLSQP", bounds=[(u_lo, u_hi)] * (N * nu),
                      constraints=[limits], options={"ftol": 1e-14, "maxiter": 1000})
    assert result.success, result.message
    return result.x[:nu], result.x


@pytest.mark.parametrize("solver", ["osqp", "daqp"])
@pytest.mark.parametrize("soft", [False, True])
def test_constrained_first_move_equals_a_second_qp_solver(soft, solver):
    """Box inputs and an output limit, both active, on time-varying affine stages: OSQP's first
    move (tolerance 1e-9, polished), and DAQP's (its active set's exact solution), equal SLSQP's
    on the independently written problem with hard
    limits; the soft limits' exact penalty (rho_l = 1e3 above the multiplier) gives the same move.
    SLSQP stops when the cost (~10) changes by under 1e-14: its moves are right to ~1e-7; asserted
    to 1e-6 of the input scale."""
    rng, A, B, C, D = random_system(7, nx=3, nu=2, ny=2)
    free = zoh(A, B, 0.1)
    pushed = zoh(A - 0.5 * np.eye(3), B, 0.1, e=np.array([0.05, -0.02, 0.0]))
    stages = [free if k % 3 else pushed for k in range(8)]
    Q, R, g, r = np.diag([5.0, 1.0]), 0.1 * np.eye(2), np.array([0.1, 0.0]), np.array([1.5, -1.0])
    H, h, hi = np.array([C[0]]), np.array([0.1]), np.array([0.5])  # unconstrained, it reaches 0.626
    x0, u_max = np.array([0.2, -0.1, 0.3]), 0.6
    mpc = LinearMPC(free, C, D, g, Q, R, 8, u_min=[-u_max] * 2, u_max=[u_max] * 2, H=H, h=h, hi=hi,
                    eps=1e-9, rho_l=1e3, rho_q=1e3, soft=soft, max_iter=20000, solver=solver)
    plan = mpc.solve(x0, r, stages=stages)
    assert plan.status == "solved"
    first, U = _reference_first_move(stages, x0, C, D, g, Q, R, r, -u_max, u_max, H, h, hi)
    assert np.isclose(np.abs(U), u_max, atol=1e-9).any()  # the box binds
    assert plan.slack < 1e-7  # feasible: the exact penalty leaves the limit hard
    limited = plan.x[1:] @ H[0] + h[0]
    assert limited.max() == pytest.approx(hi[0], abs=1e-6)  # and the output limit binds
    np.testing.assert_allclose(plan.u0, first, atol=1e-6 * u_max)


def test_closed_loop_on_the_linear_model_keeps_its_limits():
    """A double integrator (a 1 kg mass, Ts = 10 ms) sent to x = 1 m with |u| <= 2 N and the hard
    limit x <= 0.8 m, run in closed loop on its own exact discretisation. The horizon (1 s) is
    longer than the longest braking (1.3 m/s at 2 m/s^2: 0.65 s), so every problem stays feasible.
    OSQP (eps 1e-6) meets each row to eps_abs + eps_rel |row| <= 1e-6 + 1e-6 x 2: the applied
    inputs and the states keep the limits to 3e-6, and it comes to rest on the limit."""
    stage = zoh(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), 0.01)
    mpc = LinearMPC(stage, np.eye(2), np.zeros((2, 1)), np.zeros(2), np.diag([100.0, 1.0]), np.eye(1) * 0.01, 100,
                    u_min=[-2.0], u_max=[2.0], H=np.array([[1.0, 0.0]]), hi=[0.8], eps=1e-6, soft=False)
    x, us, xs = np.zeros(2), [], []
    for _ in range(300):
        plan = mpc.solve(x, np.array([1.0, 0.0]))
        assert plan.status == "solved"
        x = stage.A @ x + stage.B @ plan.u0
        us.append(plan.u0[0])
        xs.append(x.copy())
    us, xs = np.array(us), np.array(xs)
    assert np.abs(us).max() <= 2.0 + 3e-6
    assert np.abs(us).max() >= 2.0 - 3e-6  # the input limit was active on the way
    assert xs[:, 0].max() <= 0.8 + 3e-6
    assert xs[-1] == pytest.approx([0.8, 0.0], abs=1e-5)


def test_a_known_disturbance_makes_tracking_offset_free():
    """The same mass pushed by a constant 0.5 N it cannot see: told the disturbance (B d added to
    every stage, and -d as the input's reference, the effort that holds it) it comes to rest on
    the reference, since its prediction is then the plant; not told, its feedback holds the push
    only with a position error (0.5 N over its position gain, ~1e-3 m)."""
    stage = zoh(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), 0.01)
    push = stage.B[:, 0] * 0.5

    def rest(disturbance, ur):
        mpc = LinearMPC(stage, np.eye(2), np.zeros((2, 1)), np.zeros(2), np.diag([100.0, 1.0]), np.eye(1) * 0.01,
                        50, eps=1e-10)
        x = np.zeros(2)
        for _ in range(600):
            x = stage.A @ x + stage.B @ mpc.solve(x, np.array([0.3, 0.0]), ur=ur, disturbance=disturbance).u0 + push
        return x

    assert rest(push, [-0.5]) == pytest.approx([0.3, 0.0], abs=1e-8)
    assert rest(None, None)[0] - 0.3 > 1e-4


def test_contact_mpc_names_what_the_linearization_lacks():
    """A linear model without the wrist-force input: one clear error naming it and what there is."""
    model = LinearModel(np.zeros((2, 2)), np.zeros((2, 1)), np.zeros((1, 2)), np.zeros((1, 1)),
                        ["x", "v"], ["u[1]"], ["y[1]"])
    task = PressTask([0, 0, -0.1], [0, 0, -1.15], [0, 0, 1], 2e5, 2e3, 1e4, 10.0, 1.0, 1e-4, [-1] * 3, [1] * 3,
                     25.0, 2e-3, 10)
    with pytest.raises(ValueError, match="the linear model has no input 'f' \\(its inputs: u\\[1\\]\\)"):
        PlaneContactMpc(model, task)


@pytest.mark.parametrize("solver", ["osqp", "daqp"])
def test_a_copy_of_the_mpc_plans_as_the_original(solver):
    """fmi2GetFMUstate deep-copies the component: the copy (and a pickled one) sets up its own
    solver from the same matrices (OSQP: and warm start), and plans the next move as the original
    does, to OSQP's tolerance (1e-6 relative on the input, eps 1e-6; DAQP's plan is exact)."""
    import copy
    import pickle

    stage = zoh(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), 0.01)
    mpc = LinearMPC(stage, np.eye(2), np.zeros((2, 1)), np.zeros(2), np.diag([100.0, 1.0]), np.eye(1) * 0.01, 50,
                    u_min=[-2.0], u_max=[2.0], H=np.array([[1.0, 0.0]]), hi=[0.8], eps=1e-6, solver=solver)
    x = np.array([0.1, 0.2])
    mpc.solve(x, np.array([1.0, 0.0]))
    copies = (copy.deepcopy(mpc), pickle.loads(pickle.dumps(mpc)))
    want = mpc.solve(x, np.array([1.0, 0.0])).u0
    for other in copies:
        assert other.solve(x, np.array([1.0, 0.0])).u0 == pytest.approx(want, rel=1e-6, abs=1e-6)


def _two_mode_problem():
    """Time-varying stages of two kinds (the contact modes of the module docstring), an active box
    and an active soft output limit."""
    rng, A, B, C, D = random_system(7, nx=3, nu=2, ny=2)
    free = zoh(A, B, 0.1)
    pushed = zoh(A - 0.5 * np.eye(3), B, 0.1, e=np.array([0.05, -0.02, 0.0]))
    kw = dict(C=C, D=D, g=np.array([0.1, 0.0]), Q=np.diag([5.0, 1.0]), R=0.1 * np.eye(2), N=8, u_min=[-0.6] * 2,
              u_max=[0.6] * 2, H=np.array([C[0]]), h=np.array([0.1]), hi=np.array([0.5]), rho_l=1e3, rho_q=1e3,
              eps=1e-6, max_iter=20000)
    return free, pushed, kw


@pytest.mark.parametrize("solver", ["osqp", "daqp"])
def test_a_kept_mode_solver_plans_as_a_fresh_one(solver):
    """Switching between two stage sequences back and forth: the solver kept for each mode (set up
    once) gives, at every switch, the plan that a solver set up afresh for that sequence gives
    (``modes=1`` condenses and factorizes again at every switch), both polished: to 1e-9 of the
    input scale (the active set's equality QP, solved twice, agrees to rounding)."""
    free, pushed, kw = _two_mode_problem()
    sequences = ([free] * 8, [free if k % 3 else pushed for k in range(8)])
    kept, fresh = LinearMPC(free, solver=solver, **kw), LinearMPC(free, modes=1, solver=solver, **kw)
    rng = np.random.default_rng(3)
    for k in range(8):
        x0, r = 0.3 * rng.normal(size=3), np.array([1.5, -1.0])
        a, b = kept.solve(x0, r, stages=sequences[k % 2]), fresh.solve(x0, r, stages=sequences[k % 2])
        assert a.polished and b.polished
        np.testing.assert_allclose(a.u, b.u, rtol=0.0, atol=1e-9 * 0.6)
    assert len(kept._modes) == 2 and len(fresh._modes) == 1


@pytest.mark.parametrize("solver", ["osqp", "daqp"])
def test_a_polished_plan_does_not_depend_on_the_iteration_path(solver):
    """The same problem solved cold and warm-started from an unrelated plan: ADMM takes other
    iterates (and counts), polishing lands both on the active set's solution, equal to 1e-9 of the
    input scale, far below OSQP's 1e-6 tolerance: what another machine's rounding would change
    in the iterations does not reach the plan."""
    free, pushed, kw = _two_mode_problem()
    stages = [free if k % 3 else pushed for k in range(8)]
    x0, r = np.array([0.2, -0.1, 0.3]), np.array([1.5, -1.0])
    cold = LinearMPC(free, solver=solver, **kw).solve(x0, r, stages=stages)
    warm = LinearMPC(free, solver=solver, **kw)
    warm.solve(-x0, -r, stages=stages)  # a plan elsewhere to start the next solve from
    second = warm.solve(x0, r, stages=stages)
    assert cold.polished and second.polished and cold.iterations != second.iterations
    np.testing.assert_allclose(second.u, cold.u, rtol=0.0, atol=1e-9 * 0.6)


@pytest.mark.parametrize("c, want", [((3.0, -5.0), (1.5, -5.0)), ((1.0, 1.0), (0.5, 0.5)), ((-3.0, 0.0), (-1.0, 0.0))])
def test_active_set_qp_reads_single_entry_rows_as_bounds(c, want):
    """min 1/2 |x - c|^2 s.t. -4 <= -2 x0 <= 2 (a scaled, negative bound row), x0 <= 1.5 (a second
    bound on x0: the two intersect), x0 + x1 <= 1 (a general row): the closed form is c clipped to
    x0 in [-1, 1.5] or, when x0 + x1 <= 1 binds, c projected onto the line x0 + x1 = 1."""
    A = np.array([[-2.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    l, u = np.array([-4.0, -np.inf, -np.inf]), np.array([2.0, 1.5, 1.0])
    qp = DenseActiveSetQP(np.eye(2), -np.asarray(c), A, l, u)
    found = qp.solve()
    assert found.solved and found.status == "solved"
    np.testing.assert_allclose(found.x, want, rtol=0.0, atol=1e-12)


@pytest.mark.parametrize("solver", ["osqp", "daqp"])
def test_a_copy_keeps_a_solver_for_every_mode(solver):
    """A deep copy (fmi2GetFMUstate) and a pickled copy set up a solver for each mode the original
    kept, keyed by the copy's own stages, and plan both modes as the original does (to OSQP's
    tolerance, eps 1e-6 relative; DAQP's plans are exact) without condensing again."""
    import copy
    import pickle

    free, pushed, kw = _two_mode_problem()
    sequences = ([free] * 8, [free if k % 3 else pushed for k in range(8)])
    mpc = LinearMPC(free, solver=solver, **kw)
    x0, r = np.array([0.2, -0.1, 0.3]), np.array([1.5, -1.0])
    mpc.solve(x0, r, stages=sequences[1])
    mpc.solve(x0, r, stages=sequences[0])
    for other in (copy.deepcopy((mpc, sequences)), pickle.loads(pickle.dumps((mpc, sequences)))):
        twin, their = other
        assert len(twin._modes) == 2
        twin._condense = None  # a copy that condensed again would fail here
        for k in (1, 0, 1):
            want = mpc.solve(x0 * (1 + k), r, stages=sequences[k]).u
            np.testing.assert_allclose(twin.solve(x0 * (1 + k), r, stages=their[k]).u, want, rtol=1e-6, atol=1e-6)
