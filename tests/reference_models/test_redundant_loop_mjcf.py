"""A redundantly closed MJCF loop (tests/data/mjcf/parallelogram_extra_crank.xml): its DOF by the rank
of the constraint Jacobian is 1 where Grübler's count says 0, and MuJoCo's soft connects carry its
redundant loop to the closed-form motion (issue 37)."""

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


def test_import_refuses_it_by_name_until_the_kernel_runs_on_the_selected_rows():
    """Today's refusal says what the linkage is (one line, the reason), not only Grübler's count."""
    import pytest

    from loopcheck.reference_models.mjcf_import import MjcfError, import_mjcf

    with pytest.raises(MjcfError) as info:
        import_mjcf(MODEL)
    message = str(info.value)
    assert "\n" not in message and "0 degrees of freedom by Grübler's count" in message
    assert "redundantly closed loop" in message and "not accepted yet" in message
