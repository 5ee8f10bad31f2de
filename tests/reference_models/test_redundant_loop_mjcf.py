"""Redundantly closed MJCF loops (issue 37): tests/data/mjcf/parallelogram_extra_crank.xml, whose DOF by the
rank of the constraint Jacobian is 1 where Grübler's count says 0 (MuJoCo's soft connects carry its redundant
loop to the closed-form motion), and tests/data/mjcf/coaxial_arms_pinned.xml (Genesis' two coaxial arms
pinned at their tips). Both are imported and checked with Grübler's count as a warning."""

from pathlib import Path

import mujoco
import numpy as np

from loopcheck.kinematics import independent_rows, rank_dof

MODEL = Path(__file__).parent.parent / "data" / "mjcf" / "parallelogram_extra_crank.xml"
I_EFF = 3 * (0.05 + 1.0 * 0.35 ** 2) + 2.0 * 0.7 ** 2   # kg·m² about the input (the file's comment)


def _assembled():
    m = mujoco.MjModel.from_xml_path(str(MODEL))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    return m, d


def test_rank_of_the_connects_leaves_one_dof_where_grubler_leaves_none():
    m, d = _assembled()
    assert np.max(np.abs(d.efc_pos)) < 1e-12          # the keyframe closes both loops
    J = d.efc_J.reshape(d.nefc, m.nv)                  # dense: two connects, 3 rows each
    assert J.shape == (6, 4)
    assert 3 * 4 - 2 * 6 == 0                          # Grübler: 4 moving bodies, 4 hinges + 2 pins
    assert len(independent_rows(J)) == 3               # the z rows are zero, one in-plane row redundant
    assert rank_dof(J) == 1


def test_mujoco_follows_the_mechanism_without_its_redundant_crank():
    """MuJoCo against the closed form θ = 0.4 + ½ t²/I over 1 s; its connects are soft, so the
    tolerance is its constraint violation's scale, measured 3.9e-5 rad and 2.2e-5 m: 1e-4."""
    m, d = _assembled()
    worst = violation = 0.0
    while d.time < 0.5 - 1e-12:
        mujoco.mj_step(m, d)
        theta = 0.4 + 0.5 * d.time ** 2 / I_EFF
        worst = max(worst, float(np.max(np.abs(d.qpos - [theta, -theta, theta, theta]))))
        violation = max(violation, float(np.max(np.abs(d.efc_pos))))
    assert worst < 1e-4 and violation < 1e-4


GRUBLER_WARNING = ("Grübler's count gives 0 degrees of freedom, the rank of the loop equations at the start gives 1 "
                   "({k} of its {m} loop equations are redundant): a redundantly closed loop, run with one degree "
                   "of freedom on its independent equations")


def test_import_accepts_it_with_grublers_count_as_a_warning():
    from loopcheck.reference_models.mjcf_import import import_mjcf

    imported = import_mjcf(MODEL)
    assert GRUBLER_WARNING.format(k=1, m=4) in imported.warnings
    assert imported.scene.mechanism.linkage.grubler_dof == 0


COAXIAL = Path(__file__).parent.parent / "data" / "mjcf" / "coaxial_arms_pinned.xml"
I_ARMS = (0.02 + 1.0 * 0.25 ** 2) + (0.01 + 0.6 * 0.3 ** 2)   # kg·m² about the common axis (the file's comment)


def test_coaxial_arms_pinned_at_their_tips_turn_as_one_body():
    """Genesis' two coaxial arms pinned at their tips: Grübler 0, rank 1 DOF. The import accepts it with the
    warning; the reduced engine (DOP853 rtol 1e-12) follows θ0 + ω0 t + ½ (T/(I1 + I2)) t², measured 4e-15
    rad (bound 1e-11: the integrator's rtol, not a lost arm, which changes θ(1 s) by 0.5 rad); `loopcheck check`
    passes as written (MuJoCo's soft connect: its loops open up to 8.5e-6 m, θ̇ within 1.3e-4 rad/s)."""
    from loopcheck.compare.cli import main
    from loopcheck.reduced import ReducedSettings, simulate
    from loopcheck.reference_models.mjcf_import import import_mjcf

    imported = import_mjcf(COAXIAL)
    assert GRUBLER_WARNING.format(k=1, m=2) in imported.warnings
    scene = imported.scene
    tr = simulate(scene, ReducedSettings(method="dop853", rtol=1e-12)).trajectory
    T, q0, w0 = 0.3, 0.3, 0.5
    assert np.max(np.abs(tr.q - (q0 + w0 * tr.t + 0.5 * T / I_ARMS * tr.t ** 2))) < 1e-11
    assert np.max(np.abs(tr.qdot - (w0 + T / I_ARMS * tr.t))) < 1e-11
    assert main(["check", str(COAXIAL)]) == 0


def test_check_of_the_parallelogram_with_an_extra_crank_passes_and_warns(capsys):
    from loopcheck.compare.cli import main

    assert main(["check", str(MODEL)]) == 0
    captured = capsys.readouterr()
    assert captured.out.strip().endswith("1 passed, 0 failed")
    assert f"loopcheck: warning: {MODEL}: {GRUBLER_WARNING.format(k=1, m=4)}" in captured.err.splitlines()
