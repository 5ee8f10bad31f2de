"""DOF from the rank of the loop Jacobian, not Grübler's count (issue 37).

A parallelogram with an extra crank (three equal parallel cranks from ground joined by one
coupler) and two coaxial arms pinned at their tips are redundantly closed: Grübler's count
3·n − 2·j gives 0, yet each moves with one degree of freedom. :func:`independent_rows` picks the
independent rows of Φ_x by a rank-revealing QR; Newton's assembly, K and L on those rows only
must reproduce the mechanism without the redundant link (closed form: every crank turns as the
input, the coupler translates), and the dropped rows must stay satisfied along the motion.

The loops are written here in numpy by hand: the oracle is independent of the package's tables.
"""

import numpy as np
import pytest

from loopcheck.kinematics import RANK_RTOL, independent_rows, rank_dof

A = 0.7          # crank length (m)
PIVOTS = (0.0, 1.1, 2.3)   # the three cranks' ground pivots on the x axis (m)


def e(t):
    return np.array([np.cos(t), np.sin(t)])


def ep(t):
    return np.array([-np.sin(t), np.cos(t)])


def phi(x):
    """x = (θ1, θ2, θ3, θc). Coupler pins at crank tips; the coupler's pins lie at PIVOTS[k] − PIVOTS[0]
    along it. Loop k (k = 2, 3): crank 1 → coupler → crank k's tip = ground pivot k + crank k."""
    t1, t2, t3, tc = x
    rows = []
    for k, tk in ((1, t2), (2, t3)):
        d = PIVOTS[k] - PIVOTS[0]
        rows.append(PIVOTS[0] * e(0) + A * e(t1) + d * e(tc) - PIVOTS[k] * e(0) - A * e(tk))
    return np.concatenate(rows)


def jac(x):
    t1, t2, t3, tc = x
    J = np.zeros((4, 4))
    for r, (k, col) in enumerate(((1, 1), (2, 2))):
        d = PIVOTS[k] - PIVOTS[0]
        J[2 * r:2 * r + 2, 0] = A * ep(t1)
        J[2 * r:2 * r + 2, col] = -A * ep(x[col])
        J[2 * r:2 * r + 2, 3] = d * ep(tc)
    return J


DRIVE = np.array([1.0, 0.0, 0.0, 0.0])


def newton(q, x, rows):
    """Newton on the selected rows and the drive θ1 = q."""
    for _ in range(50):
        F = np.concatenate([phi(x)[list(rows)], [DRIVE @ x - q]])
        if np.max(np.abs(F)) <= 1e-14:
            break
        x = x - np.linalg.solve(np.vstack([jac(x)[list(rows)], DRIVE]), F)
    return x


def test_parallelogram_with_extra_crank_has_one_dof_by_rank_not_grubler():
    x = np.array([0.9, 0.9, 0.9, 0.0])
    assert np.max(np.abs(phi(x))) < 1e-15
    n_moving, n_joints = 4, 6
    assert 3 * n_moving - 2 * n_joints == 0          # Grübler's count refuses it
    rows = independent_rows(jac(x))
    assert len(rows) == 3                            # four loop rows, rank 3
    assert rank_dof(jac(x)) == 1


def test_selected_rows_give_the_motion_of_the_linkage_without_its_redundant_link():
    x = np.array([0.4, 0.4, 0.4, 0.0])
    rows = independent_rows(jac(x))       # chosen once, at the assembled configuration
    dropped = [r for r in range(4) if r not in rows]
    assert len(dropped) == 1
    for q in np.linspace(0.4, 2.6, 23):  # through the upright position, away from the flat ones
        x = newton(q, x + 0.01, rows)
        # the oracle: a parallelogram's cranks all turn as the input, its coupler translates
        np.testing.assert_allclose(x, [q, q, q, 0.0], atol=1e-12)
        # the redundant row stays satisfied (m); round-off of lengths ~1 m
        assert np.max(np.abs(phi(x)[dropped])) < 1e-12
        K = np.linalg.solve(np.vstack([jac(x)[list(rows)], DRIVE]), [0, 0, 0, 1.0])
        np.testing.assert_allclose(K, [1.0, 1.0, 1.0, 0.0], atol=1e-12)


def test_coaxial_arms_pinned_at_their_tips_have_one_dof():
    """Two arms of length 0.5 on one pivot, pinned at their tips: Φ = 0.5 (e(θ1) − e(θ2))."""
    for t in (0.0, 0.7, 2.0, -2.9):
        J = 0.5 * np.array([np.r_[-np.sin(t), np.sin(t)], np.r_[np.cos(t), -np.cos(t)]])
        assert 3 * 2 - 2 * 3 == 0
        rows = independent_rows(J)
        assert len(rows) == 1 and rank_dof(J) == 1
        # the kept row is the larger component: it drives θ2 with θ1 (K = (1, 1))
        K = np.linalg.solve(np.vstack([J[list(rows)], [1.0, 0.0]]), [0.0, 1.0])
        np.testing.assert_allclose(K, [1.0, 1.0], atol=1e-15)


def test_tolerance_is_relative_and_stated():
    J = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    assert len(independent_rows(J)) == 2   # any two of the three: pivoting takes the largest first
    # a row off the span by 1e-6 × the scale is independent; one by 1e-12 is round-off
    Jb = J.copy()
    Jb[2, 2] = 1e-6
    assert len(independent_rows(Jb)) == 3
    Jb[2, 2] = 1e-12
    assert len(independent_rows(Jb)) == 2 and RANK_RTOL == 1e-9
    # scaling every row by 1e6 (units) changes nothing
    assert independent_rows(1e6 * Jb) == independent_rows(Jb)


@pytest.mark.parametrize("bad", [np.zeros(3), np.array([[np.nan, 1.0]])])
def test_malformed_jacobian_refused(bad):
    with pytest.raises(ValueError):
        independent_rows(bad)


# -- the compiled kernel on the selected rows ------------------------------------------------

def _kernel_parallelogram(select=None):
    """The same two loop vectors as ``phi`` above, as the kernel's term table (x = (θ1, θ2, θ3, θc))."""
    from loopcheck.kernels import loops as kl
    from loopcheck.kinematics import TermTable, pack

    offset, row, coef, mag, angle, phase = [], [], [], [], [], []
    for k, col in ((1, 1), (2, 2)):
        offset.append((PIVOTS[0] - PIVOTS[k], 0.0))
        for c, a in ((A, 0), (PIVOTS[k] - PIVOTS[0], 3), (-A, col)):
            row.append(k - 1), coef.append(c), mag.append(-1), angle.append(a), phase.append(0.0)
    table = TermTable(np.array(offset), np.array(row), np.array(coef, dtype=float), np.array(mag),
                      np.array(angle), np.array(phase))
    F, I = pack(4, 4, (table,))
    return kl.Loops(F, I, select)


def test_kernel_reports_every_row_and_runs_on_the_selected_ones():
    x = np.array([0.9, 0.9, 0.9, 0.0])
    phi_all, J_all = _kernel_parallelogram().all_constraints(x)
    np.testing.assert_allclose(J_all, jac(x), atol=1e-15)
    np.testing.assert_allclose(phi_all, phi(x), atol=1e-15)
    chosen = (1, 2, 3)                   # independent here (not the first three: a plant that ignores
    assert len(independent_rows(J_all[list(chosen)])) == 3   # the selection runs on rows 0, 1, 2)
    phi_sel, J_sel = _kernel_parallelogram(np.array(chosen)).constraints(x)
    np.testing.assert_array_equal(J_sel, J_all[list(chosen)])
    np.testing.assert_array_equal(phi_sel, phi_all[list(chosen)])


@pytest.mark.parametrize("pick", ["qr", "last_three"])
def test_kernel_newton_k_and_l_on_independent_rows_match_the_linkage_without_its_redundant_crank(pick):
    """Newton's assembly, K and L of the compiled kernel on three of the four rows; the oracle is
    the parallelogram's closed form (every crank turns as the input, the coupler translates: K = (1, 1,
    1, 0), L = 0); the dropped row stays satisfied. Tolerances: 1e-12 (Newton's tol, lengths ~1 m)."""
    from loopcheck.kernels import loops as kl

    x = np.array([0.4, 0.4, 0.4, 0.0])
    J_all = _kernel_parallelogram().all_constraints(x)[1]
    rows = independent_rows(J_all) if pick == "qr" else (1, 2, 3)
    kernel = _kernel_parallelogram(np.array(rows))
    full = _kernel_parallelogram()
    dropped = [r for r in range(4) if r not in rows]
    for q in np.linspace(0.4, 2.6, 12):
        guess = x + np.array([0.0, 0.02, -0.02, 0.01])
        status, _, _ = kernel.assemble(q, guess, DRIVE, 1e-12, 50, 1e-9)
        assert status == kl.CLOSED
        np.testing.assert_allclose(guess, [q, q, q, 0.0], atol=1e-12)
        x = guess
        assert np.max(np.abs(full.all_constraints(x)[0][dropped])) < 1e-12
        c, K, L = kernel.coefficients(x, DRIVE)
        assert c > 1e-3
        np.testing.assert_allclose(K, [1.0, 1.0, 1.0, 0.0], atol=1e-12)
        np.testing.assert_allclose(L, 0.0, atol=1e-10)   # A's condition (~1/c ≲ 1e2) × Newton's 1e-12


def test_kernel_refuses_a_selection_that_is_not_n_minus_1_distinct_rows():
    for bad in ([0, 1, 2, 3], [0, 1], [0, 0, 1], [0, 1, 4]):
        with pytest.raises(ValueError, match="select must be 3 distinct rows of the 4 constraint rows"):
            _kernel_parallelogram(np.array(bad))
