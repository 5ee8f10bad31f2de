"""The one singular-position measure (docs/physics.md, "Singular positions"): defined once, in
:mod:`loopcheck.kinematics`, and giving the same verdict wherever a verdict is taken.

Oracle: four-bars built with a known conditioning. The ground pivot O3 is placed so that the two
links of the input's dyad meet at B at an angle ε: for the crank's input (O1) the coupler and
the rocker, for the relative angle at A the line O1→B (crank and coupler turning together) and
the rocker. The conditioning of the input is then |sin ε| by construction (the Hadamard ratio of
the dyad's two columns of Φ_x, which depend on the angles alone, not on where O3 is).
"""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

import numpy as np
import pytest

from loopcheck import kinematics as loops
from loopcheck.errors import NumericalFailure
from loopcheck.reduced import MechanismModel
from loopcheck.reduced.kernels import physics
from loopcheck.scene import SceneError
from loopcheck.scenefile import _check_start, scene_from_dict

from helpers import ROOT

C1, C2, C3 = 0.5, 0.9, 0.7  # m
CRANK, COUPLER = 0.3, 0.5  # rad, the frames' absolute angles
# Each side of the threshold by a margin the computed measure cannot cross: its relative error
# at 1e-9 is ~ε_machine / 1e-9 ≈ 2e-7 (θ3 − φ1 rounded to an ulp of 0.5 rad).
SIDES = {"above": 1.25, "below": 0.8}
# The computed conditioning against sin ε: measured 4.0e-8 relative at most; bound 4e-7.
ORACLE_RTOL = 4e-7


def _near_dead_centre(input_joint: str, c: float):
    """A four-bar scene of the seed's lengths with its input ``input_joint`` ("O1": the crank's
    angle, "A": the coupler's angle relative to the crank) at conditioning c, and that
    configuration x (crank, coupler, rocker frame angles)."""
    a = C1 * np.array([math.cos(CRANK), math.sin(CRANK)])
    b = a + C2 * np.array([math.cos(COUPLER), math.sin(COUPLER)])
    other = COUPLER if input_joint == "O1" else math.atan2(b[1], b[0])  # the dyad's other link at B
    rocker = other + math.asin(c)
    o3 = b - C3 * np.array([math.cos(rocker), math.sin(rocker)])
    x = np.array([CRANK, COUPLER, rocker])
    q = CRANK if input_joint == "O1" else COUPLER - CRANK
    scene = scene_from_dict({
        "name": "near_dead_centre", "simulation": {"horizon": 0.1},
        "linkage": {"type": "planar", "input": input_joint},
        "bodies": {"ground": {"points": {"O1": [0.0, 0.0], "O3": o3.tolist()}},
                   "crank": {"points": {"O1": [0.0, 0.0], "A": [C1, 0.0]}, "pivot_inertia": 1.5, "pivot": "O1"},
                   "coupler": {"points": {"A": [0.0, 0.0], "B": [C2, 0.0]}, "mass": 40.0, "com": [0.5, 0.1],
                               "inertia": 5.0},
                   "rocker": {"points": {"O3": [0.0, 0.0], "B": [C3, 0.0]}, "pivot_inertia": 3.5, "pivot": "O3"}},
        "joints": [{"name": "O1", "type": "revolute", "a": "ground.O1", "b": "crank.O1"},
                   {"name": "A", "type": "revolute", "a": "crank.A", "b": "coupler.A"},
                   {"name": "B", "type": "revolute", "a": "coupler.B", "b": "rocker.B"},
                   {"name": "O3", "type": "revolute", "a": "ground.O3", "b": "rocker.O3"}],
        "initial": {"q": q, "guess": {"crank": CRANK, "coupler": COUPLER, "rocker": rocker}}})
    return scene, x


@pytest.mark.parametrize("side", SIDES)
@pytest.mark.parametrize("input_joint", ["O1", "A"])
def test_each_side_of_the_threshold_numpy_and_compiled_code_agree(input_joint, side):
    """The input's conditioning is sin ε; every place that judges it gives the verdict of its
    side: the numpy coefficients, the scene file's check of a start with speed, the compiled
    core's kinematics at the input's row and (for the crank, a coordinate) the start of its chart."""
    c = SIDES[side] * loops.SINGULAR_CONDITIONING
    scene, x = _near_dead_centre(input_joint, c)
    system = loops.compile_linkage(scene.mechanism.linkage)
    measured = loops.driving_conditioning(system, x)
    assert measured == pytest.approx(c, rel=ORACLE_RTOL, abs=0.0)
    singular = side == "below"

    def refused(call, error) -> bool:
        try:
            call()
        except error:
            return True
        return False

    model = MechanismModel(scene)
    verdicts = {
        "numpy coefficients": refused(lambda: loops.coefficients(system, x), NumericalFailure),
        "scene file start": refused(lambda: _check_start(system, x, 0.0, 1.0), SceneError),
        "compiled kinematics_at": refused(lambda: model.coefficients_at(x), NumericalFailure),
    }
    chart = model.new_chart()
    if input_joint == "O1":
        verdicts["compiled chart start"] = not chart.start(x, system.coordinate("crank.angle"))
    assert verdicts == dict.fromkeys(verdicts, singular)
    if input_joint == "O1" and not singular:  # the compiled core's own value: the chart's conditioning
        # (measured equal to numpy's; bound 1e-12: its LU and LAPACK's determinant may round apart)
        assert chart.arrays()["fields"][physics.CONDITIONING] == pytest.approx(measured, rel=1e-12)


def test_the_conditioning_of_a_coordinate_is_the_measure_with_that_coordinate_driving():
    """loops.conditioning (each coordinate, the partitioning's choice) is driving_conditioning
    with row e_j, and for the crank of the seed four-bar |sin(φ2 − φ1)| (the closed form)."""
    scene, x = _near_dead_centre("O1", 0.3)
    system = loops.compile_linkage(scene.mechanism.linkage)
    each = loops.conditioning(system, x)
    for j, row in enumerate(np.eye(system.n)):
        assert each[j] == loops.driving_conditioning(system, x, row)
    assert each[0] == pytest.approx(0.3, rel=1e-15)  # measured equal; bound ~4 ulps


def test_the_measure_is_scale_free():
    """The same linkage 1000× larger, or turned, has the same conditioning (measured: equal, and
    1 ulp apart; bound 10 ulps). The SVD ratio of [Φ_x; c], the measure before, went from 0.076
    to 0.00095 on this linkage 1000× larger: it depended on the unit of length."""
    scene, x = _near_dead_centre("A", 0.2)
    system = loops.compile_linkage(scene.mechanism.linkage)
    J = loops.constraint_jacobian(system, x)
    turn = np.array([[math.cos(1.0), -math.sin(1.0)], [math.sin(1.0), math.cos(1.0)]])
    for changed in (1000.0 * J, turn @ J):  # one loop: two rows, x and y
        assert abs(loops.hadamard_ratio(loops.dependent_jacobian(changed, system.drive))) == pytest.approx(
            loops.driving_conditioning(system, x), rel=2e-15)


# -- one definition --------------------------------------------------------------------

NAMES = re.compile(r"singular|rcond|conditioning|determinant", re.IGNORECASE)


def _defined_thresholds(path: Path) -> list[str]:
    """Names like SINGULAR_*, *_RCOND, *CONDITIONING*, *DETERMINANT* given a real number in a
    source file (a module constant, a compiled copy ``cython.declare(cython.double, value)``, an
    argument's default)."""
    text = path.read_text(encoding="utf-8")
    if not NAMES.search(text):  # every name found matches NAMES: a file without a match has none
        return []
    tree = ast.parse(text)
    found = []

    def numeric(node) -> bool:
        """A real number (not a status code, an int), or a compiled copy of one."""
        if isinstance(node, ast.Constant) and isinstance(node.value, float):
            return True
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "declare" and node.args:
            return getattr(node.args[0], "attr", "") == "double"  # cython.declare(cython.double, VALUE)
        return isinstance(node, ast.BinOp) and (numeric(node.left) or numeric(node.right))

    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None and numeric(node.value):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            found += [t.id for t in targets if isinstance(t, ast.Name) and NAMES.search(t.id)]
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args.args + node.args.kwonlyargs
            defaults = [None] * (len(node.args.args) - len(node.args.defaults)) + node.args.defaults + node.args.kw_defaults
            found += [a.arg for a, d in zip(args, defaults) if d is not None and numeric(d) and NAMES.search(a.arg)]
    return [f"{path.relative_to(ROOT)}:{name}" for name in found]


def test_the_singular_threshold_is_defined_once():
    """Exactly one singular-position threshold in the package: loopcheck.kinematics'. The compiled
    core takes it as an argument (a .pxd declares no copy of it), the four-bar oracle and every
    other check import it. Planted: SINGULAR_CONDITIONING = 1e-9 back in
    loopcheck/reduced/kernels/physics.py fails this test, naming it."""
    sources = sorted((ROOT / "loopcheck").rglob("*.py"))
    found = [name for path in sources for name in _defined_thresholds(path)]
    assert found == ["loopcheck/kinematics.py:SINGULAR_CONDITIONING"], found
    declared = [f"{p.relative_to(ROOT)}: {line.strip()}" for p in sorted((ROOT / "loopcheck").rglob("*.pxd"))
                for line in p.read_text(encoding="utf-8").splitlines()
                if line.lstrip().startswith("cdef") and NAMES.search(line) and "readonly double singular" not in line]
    assert declared == [], declared


def test_assembly_modes_closed_form_decides_as_hadamard_ratio():
    """assembly_modes's 2 × 2 closed form (kinematics._mode_signs) gives exactly the modes of
    hadamard_ratio's LU, near-singular blocks around SINGULAR_CONDITIONING (left to the LU within
    MODE_MARGIN of it), zero columns and scales from 1e-8 to 1e8 included."""
    from loopcheck import kinematics

    rng = np.random.default_rng(3)
    blocks = rng.normal(size=(4000, 2, 2)) * 10.0 ** rng.uniform(-8, 8, size=(4000, 1, 1))
    t = rng.normal(size=4000)
    eps = 10.0 ** rng.uniform(-18, -6, size=4000) * rng.choice([-1, 1], 4000)
    blocks[::2, :, 1] = blocks[::2, :, 0] * t[::2, None] + eps[::2, None] * blocks[::2, ::-1, 0] * np.array([1, -1])
    blocks[::17, :, 0] = 0.0
    # on the threshold: columns of lengths 0.1..10, turned by φ, at an angle whose sine is
    # SINGULAR_CONDITIONING within 1e-7 of it (~1e-16 absolute: where the closed form and the LU,
    # each ~1e-16 off, disagree on about one block in ten; measured max difference 1.7e-16)
    m = len(blocks[1::2][::10])
    angle = kinematics.SINGULAR_CONDITIONING * (1.0 + rng.uniform(-1e-7, 1e-7, size=m))
    phi = rng.uniform(0.0, 2 * np.pi, size=m)
    lengths = rng.uniform(0.1, 10.0, size=(m, 2))
    near = np.stack([np.stack([lengths[:, 0] * np.cos(phi), lengths[:, 1] * np.cos(phi + angle)], axis=1),
                     np.stack([lengths[:, 0] * np.sin(phi), lengths[:, 1] * np.sin(phi + angle)], axis=1)], axis=1)
    blocks[1::20] = near
    ratio = kinematics.hadamard_ratio(blocks)
    expected = np.where(np.abs(ratio) < kinematics.SINGULAR_CONDITIONING, 0, -np.sign(ratio))
    assert np.array_equal(kinematics._mode_signs(blocks), expected)
    assert np.sum(expected == 0) > 100 and np.sum(expected != 0) > 100  # both sides exercised
