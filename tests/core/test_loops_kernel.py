"""The compiled kinematics (loopcheck/kernels/loops.py, Cython) and its plain-Python source agree.

loops.py is compiled by the package's build and runs as plain Python under
``LOOPCHECK_PURE_PYTHON=1`` (the slow reference). Its integer layout constants live twice: C constants
in loops.pxd (a ``cpdef enum``) and, for plain Python, the ``if not cython.compiled`` block of
loops.py. Here the source is loaded as a second, uncompiled module beside the compiled one and both
are compared: the constants exactly, and positions, Φ, Φ_x, K, L, the conditioning and Newton's
assembly bit for bit on several shipped mechanisms (the build does not contract or reassociate,
and libm is the same). The kinematics themselves are checked against independent oracles
elsewhere (the four-bar's closed form: tests/oracles/four_bar.py, test_loops.py).
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from loopcheck import kinematics
from loopcheck.kernels import compiled, loops
from loopcheck.kinematics import SINGULAR_CONDITIONING, pack
from loopcheck.scenefile import load_scene

from helpers import ROOT

needs_compiled = pytest.mark.skipif(not compiled(), reason="the kinematics run as plain Python: nothing to compare")


def source_module():
    """loops.py loaded from its source as plain Python (a module of another name)."""
    spec = importlib.util.spec_from_file_location("loops_source", ROOT / "loopcheck" / "kernels" / "loops.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@needs_compiled
def test_the_layout_constants_are_the_same_compiled_and_as_python():
    source = source_module()
    names = [name for name in dir(source) if name.isupper() and isinstance(getattr(source, name), int)]
    assert len(names) >= 14
    for name in names:
        assert getattr(loops, name) == getattr(source, name), name
    assert source.KIN_HEADER == source.TABLES + source.N_TABLES * source.TABLE_ENTRIES


def _results(module, scene_path: str) -> np.ndarray:
    """Every output of the kernel's Python interface, flattened, along the scene's assembly:
    Φ, Φ_x, the conditioning of each coordinate, K and L with respect to the input, the centres'
    and points' positions and rates, and x assembled by Newton at inputs 0.05 apart."""
    scene = load_scene(ROOT / scene_path)
    system = kinematics.compile_linkage(scene.mechanism.linkage)
    n_angles = sum(name.endswith(".angle") for name in system.coordinate_names)
    kernel = module.Loops(*pack(system.n, n_angles, (system.loops, system.centres, system.points), system.linear,
                                system.couplings))
    x = np.array(scene.x0, dtype=float)
    q0 = float(system.drive @ x)
    out = []
    for k in range(12):
        status, _, _ = kernel.assemble(q0 + 0.05 * k, x, system.drive, 1e-12, 50, SINGULAR_CONDITIONING)
        assert status == module.CLOSED
        phi, jac = kernel.constraints(x)
        c, K, L = kernel.coefficients(x, system.drive)
        out += [x.copy(), phi, jac.ravel(), kernel.conditioning(x), [c], K, L]
        for table in (1, 2):
            out += [kernel.positions(table, x).ravel(), kernel.rates(table, x, K, L).ravel(),
                    kernel.rates(table, x, K, None).ravel()]
        out.append([kernel.driving_conditioning(x, system.joint_rows[-1])])
    return np.concatenate([np.ravel(v) for v in out])


@needs_compiled
@pytest.mark.parametrize("scene", ["scenes/seed_fourbar.toml", "scenes/mechanisms/slider_crank_gas.toml",
                                   "scenes/mechanisms/watt2_sixbar.toml", "scenes/mechanisms/andrews_squeezer.toml",
                                   "scenes/mechanisms/oscillating_slotted_lever.toml",
                                   "scenes/mechanisms/seed_fourbar_geared_flywheel.toml"])
def test_the_python_source_gives_the_compiled_numbers(scene):
    """Bit for bit: a four-bar, a slider-crank (a slider's length a coordinate, a linear row), a
    Watt six-bar (two loops), Andrews' squeezer (three loops), a slotted lever (a prismatic joint
    between moving bodies), a four-bar with a geared flywheel (a joint coupling's polynomial row)."""
    ran = _results(loops, scene)
    source = _results(source_module(), scene)
    assert np.all(np.isfinite(ran)) and ran.size > 100
    np.testing.assert_array_equal(ran, source)


def _three_by_three_cases() -> list[np.ndarray]:
    """3 × 3 matrices for the LU: every row order of the pivots (each permutation of a matrix
    with one large entry per column), random ones, one singular at each column, a zero matrix,
    a NaN and an infinity."""
    rng = np.random.default_rng(39)
    cases = [rng.normal(size=(3, 3)) for _ in range(40)]
    base = np.array([[5.0, 0.3, -0.2], [0.1, -4.0, 0.7], [-0.4, 0.2, 3.0]])
    for order in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        cases.append(base[list(order)])
    singular = rng.normal(size=(3, 3))
    cases += [np.array([[0.0, 1.0, 2.0], [0.0, 3.0, 4.0], [0.0, 5.0, 6.0]]),  # column 0 zero
              np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [3.0, 6.0, 7.0]]),  # column 1 zero after elimination
              np.vstack([singular[:2], singular[0] + singular[1]]),  # rank 2: column 2 zero to round-off
              np.zeros((3, 3)), np.array([[np.nan, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
              np.array([[1.0, 0.0, 0.0], [0.0, np.inf, 1.0], [0.0, 1.0, 1.0]])]
    return cases


def test_the_three_by_three_lu_is_the_general_one_bit_for_bit():
    """A four-bar's A = [Φ_x; row] is 3 × 3: its LU (_lu_factor3, _lu_solve3, entries in locals) must
    do the general path's operations in the general path's order. Compared on loops.py's source
    (plain Python: both paths callable) for pivots in every row order, singular matrices (each
    column's pivot 0: det 0 and the factors left as the general path leaves them), NaN and inf:
    the factors, the pivots, det and three solves, bit for bit (NaN equal to NaN)."""
    source = source_module()
    system = kinematics.compile_linkage(load_scene(ROOT / "scenes/seed_fourbar.toml").mechanism.linkage)
    fast, general = (source.Loops(*pack(system.n, 3, (system.loops,), system.linear, system.couplings))
                     for _ in range(2))
    assert fast.n == 3
    rhs = np.array([[1.0, -2.0, 0.5], [0.0, 0.0, 1.0], [3.0e-7, 1.0e3, -2.5]])
    for matrix in _three_by_three_cases():
        got = []
        for kernel, factor, solve in ((fast, fast._lu_factor3, fast._lu_solve3),
                                      (general, general._lu_factor_general, general._lu_solve_general)):
            kernel.A[:, :] = matrix
            kernel.P[:] = -1
            det = factor()
            out = [np.array([det]), np.array(kernel.A).ravel(), np.array(kernel.P, dtype=float)]
            if det != 0.0:
                for b in rhs:
                    kernel.rhs[:] = b
                    solve(kernel.rhs_at)
                    out.append(np.array(kernel.rhs))
            got.append(np.concatenate(out))
        np.testing.assert_array_equal(got[0], got[1], err_msg=f"A =\n{matrix}")
