"""Run a user's own MuJoCo model as written, and read it as the scene's coordinates.

The model is the one :func:`loopcheck.reference_models.mjcf_import.import_mjcf` read: MuJoCo steps it with
its own integrator, timestep, solver options and loop softness (``solref``/``solimp`` of its
connect equalities), from the configuration, rates and control the import read. Only the energy
flag is added (for the energy audit: MuJoCo's kinetic and potential energy); nothing else of the
model changes. :class:`ModelOptions` says what was run, and can change the options a variant
needs (a smaller step, stiffer loops) without touching anything else.

At the start of every step (after ``mj_forward``) the run records the joints' state, the input's
acceleration, the energies, the power of the motor, of the dampers and of the dry friction (its efc rows), the limits that act, and each loop's gap (the
distance between a connect's two anchors); the trajectory is the scene's input coordinate
q = drive·x with x = x_read + qpos_map (qpos − qpos_read); with several inputs, each further input
q_i = row_i·x is recorded too (``EngineResult.other_inputs``).
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from loopcheck import kinematics as loops
from loopcheck.errors import FailureReason, NumericalFailure
from loopcheck.results import ConstraintViolation, EnergyAudit, EngineResult
from loopcheck.mujoco_model.record import active_limits, friction_power, has_events, limit_note, samples_refine_extrema
from loopcheck.mujoco_model.warning_handler import bad_state, mujoco_warnings, singular_mass_matrix
from loopcheck.trajectory import JointTrajectory, Trajectory

from .mjcf_import import ConnectSource, ImportedModel, element_label, first_contact
from .settings import DEFAULT_SOLIMP, INTEGRATORS, USER_MODEL

# Work refused up front (the run keeps a dozen numbers per step): raise the timestep or shorten
# the horizon.
MAX_STEPS = 5_000_000
ENGINE = USER_MODEL  # the name of a user model's runs in comparisons and reports (a run of the engine: its RUNS)
_INTEGRATOR_NAME = {int(getattr(mujoco.mjtIntegrator, f"mjINT_{name.upper()}")): name for name in INTEGRATORS}
_CONNECT = int(mujoco.mjtEq.mjEQ_CONNECT)
_EQ_JOINT = int(mujoco.mjtEq.mjEQ_JOINT)


def _closures(model: mujoco.MjModel) -> list[int]:
    """The equalities whose softness the options set: the connects (loops) and the joint couplings,
    in the model's order."""
    return [e for e in range(model.neq) if int(model.eq_type[e]) in (_CONNECT, _EQ_JOINT)]
# MJCF's keyword for each integrator (MuJoCo's parser is case-sensitive: "euler" is refused)
MJCF_INTEGRATOR = {"euler": "Euler", "rk4": "RK4", "implicit": "implicit", "implicitfast": "implicitfast"}
_SITE = int(mujoco.mjtObj.mjOBJ_SITE)


def _number(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


@dataclass(frozen=True)
class ModelOptions:
    """What changes MuJoCo's answer on a user's model.

    integrator : one of :data:`~loopcheck.reference_models.settings.INTEGRATORS`.
    timestep : s.
    solref, solimp : per connect equality (the model's order), MuJoCo's five and two numbers.
    iterations, tolerance : the constraint solver's.
    """

    integrator: str
    timestep: float
    solref: tuple[tuple[float, float], ...]
    solimp: tuple[tuple[float, float, float, float, float], ...]
    iterations: int
    tolerance: float

    def __post_init__(self) -> None:
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {self.integrator!r}")
        if not (math.isfinite(self.timestep) and self.timestep > 0.0):
            raise ValueError(f"timestep must be positive and finite, got {self.timestep!r}")

    @classmethod
    def as_written(cls, model: mujoco.MjModel) -> "ModelOptions":
        connects = _closures(model)
        return cls(integrator=_INTEGRATOR_NAME[int(model.opt.integrator)], timestep=float(model.opt.timestep),
                   solref=tuple(tuple(float(v) for v in model.eq_solref[e]) for e in connects),
                   solimp=tuple(tuple(float(v) for v in model.eq_solimp[e]) for e in connects),
                   iterations=int(model.opt.iterations), tolerance=float(model.opt.tolerance))

    def stiff_loops(self) -> "ModelOptions":
        """The same step, the loops as stiff as MuJoCo allows at it: solref (2·timestep, 1) (the
        smallest time constant ``refsafe`` keeps) and loopcheck's solimp (0.9999, 0.9999, 0.001, 0.5, 2)."""
        n = len(self.solref)
        return replace(self, solref=((2.0 * self.timestep, 1.0),) * n, solimp=(tuple(DEFAULT_SOLIMP),) * n)

    def steps(self, horizon: float) -> int:
        """The steps of a run over ``horizon`` s (the last one may end past it)."""
        return math.ceil(horizon / self.timestep - 1e-9)

    def evaluations_per_step(self) -> int:
        return 4 if self.integrator == "rk4" else 1

    def text(self) -> str:
        """One line: integrator, step and (when all loops share them) solref and solimp."""
        line = f"{self.integrator}, timestep {self.timestep:.6g} s"
        if self.solref and len(set(self.solref)) == 1 and len(set(self.solimp)) == 1:
            line += (f", loops solref {' '.join(f'{v:g}' for v in self.solref[0])}, "
                     f"solimp {' '.join(f'{v:g}' for v in self.solimp[0])}")
        return line

    def mjcf(self, connects: tuple[ConnectSource, ...] = ()) -> str:
        """MJCF to paste into the model, enough alone to give it these options: the ``<option>``,
        the connects' softness in ``<default>`` when all share it, and a ``<connect name=...>`` line
        (``<joint name=...>`` for a joint coupling) with the values for each connect or coupling
        (``connects``: the model's, in order) that sets its own,
        which a default does not reach (every connect, when they differ); a connect without a name
        that needs its own gets a comment naming it (:func:`element_label`) and the values."""
        lines = [f'<option integrator="{MJCF_INTEGRATOR[self.integrator]}" timestep="{_number(self.timestep)}"/>']
        shared = bool(self.solref) and len(set(self.solref)) == 1 and len(set(self.solimp)) == 1
        if shared:
            lines.append(f'<default><equality solref="{" ".join(_number(v) for v in self.solref[0])}" '
                         f'solimp="{" ".join(_number(v) for v in self.solimp[0])}"/></default>')
        for k, (solref, solimp) in enumerate(zip(self.solref, self.solimp)):
            source = connects[k] if k < len(connects) else None
            if shared and (source is None or not source.own):
                continue
            values = (f'solref="{" ".join(_number(v) for v in solref)}" '
                      f'solimp="{" ".join(_number(v) for v in solimp)}"')
            if source is not None and source.name:
                lines.append(f'<{source.tag} name="{source.name}" {values}/>')
            else:
                label = source.label if source is not None else f"connect #{k + 1}"
                lines.append(f"<!-- {label}: set {values} on it -->")
        return "\n".join(lines)

    def as_dict(self) -> dict:
        return {"integrator": self.integrator, "timestep": self.timestep, "solref": [list(v) for v in self.solref],
                "solimp": [list(v) for v in self.solimp], "iterations": self.iterations, "tolerance": self.tolerance}


@dataclass(frozen=True)
class InputCoordinate:
    """The scene's input coordinate in MuJoCo's terms: q = sign·qpos + offset, where qpos is the
    input joint's own coordinate (``joint``, as :func:`element_label` names it), so that the rates
    and peaks printed (q̇) are sign·qvel. ``sign`` is −1 when the hinge's axis points against the
    plane's normal; ``offset`` is the joint's frame angle (or a slide's position) at qpos = 0."""

    joint: str
    qpos: float
    sign: float
    offset: float
    unit: str

    def text(self) -> str:
        offset = f" {'+' if self.offset >= 0 else '−'} {abs(self.offset):.12g} {self.unit}" if self.offset else ""
        return (f"{self.joint} at qpos {self.qpos:.12g} {self.unit} (q = {'' if self.sign > 0 else '−'}qpos{offset}; "
                f"every rate and peak printed is {'' if self.sign > 0 else '−'}qvel of {self.joint})")


def input_coordinate(imported: ImportedModel) -> InputCoordinate:
    """The input joint's qpos at the configuration read, and how the scene's q is made of it."""
    model, scene = imported.model, imported.scene
    mine = scene.mechanism.linkage.input_joint
    j = next(j for j in range(model.njnt)
             if imported.joint_of.get(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}") == mine)
    adr = int(model.jnt_qposadr[j])
    system = loops.compile_linkage(scene.mechanism.linkage)
    sign = float(np.sign((system.drive @ imported.qpos_map)[adr])) or 1.0
    qpos = float(imported.qpos[adr])
    offset = scene.q0 - sign * qpos
    return InputCoordinate(element_label(model, mujoco.mjtObj.mjOBJ_JOINT, j), qpos, sign,
                           0.0 if abs(offset) < 1e-12 else offset, scene.input_unit)


@dataclass(frozen=True)
class ModelRunDetails:
    """A user model's run (:attr:`EngineResult.details`): the options run and MuJoCo's version
    (``edge_warnings``: none, a control's edges are held over the step that holds them)."""

    options: ModelOptions
    mujoco_version: str
    edge_warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        return {"options": self.options.as_dict(), "mujoco_version": self.mujoco_version}


def _configured(imported: ImportedModel, options: ModelOptions) -> mujoco.MjModel:
    """A copy of the user's model with ``options`` and the energy flag set."""
    model = copy.copy(imported.model)
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{options.integrator.upper()}")
    model.opt.timestep = options.timestep
    model.opt.iterations = options.iterations
    model.opt.tolerance = options.tolerance
    model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    for e, solref, solimp in zip(_closures(model), options.solref, options.solimp):
        model.eq_solref[e] = solref
        model.eq_solimp[e] = solimp
    return model


def _gaps(model: mujoco.MjModel, data: mujoco.MjData, connects: list[int]) -> float:
    """The largest distance between a connect's two anchors (m), at the state in ``data``."""
    gap = 0.0
    for e in connects:
        if not data.eq_active[e]:
            continue
        if int(model.eq_objtype[e]) == _SITE:
            a, b = data.site_xpos[model.eq_obj1id[e]], data.site_xpos[model.eq_obj2id[e]]
        else:
            b1, b2 = model.eq_obj1id[e], model.eq_obj2id[e]
            a = data.xpos[b1] + data.xmat[b1].reshape(3, 3) @ model.eq_data[e][0:3]
            b = data.xpos[b2] + data.xmat[b2].reshape(3, 3) @ model.eq_data[e][3:6]
        gap = max(gap, float(np.linalg.norm(a - b)))
    return gap


def _actuator_forces(model: mujoco.MjModel, data: mujoco.MjData, ctrl_row: np.ndarray) -> np.ndarray:
    """Every actuator's force (MuJoCo's ``actuator_force``) at the state in ``data`` (its actuator
    length and velocity) under the controls ``ctrl_row``: gain·clamp(ctrl, ctrlrange) + b0 + b1·L + b2·L̇,
    clamped to forcerange, the force law of the actuators the import accepts (no activation dynamics,
    a fixed gain, no or an affine bias)."""
    c = np.where(model.actuator_ctrllimited, np.clip(ctrl_row, model.actuator_ctrlrange[:, 0],
                                                     model.actuator_ctrlrange[:, 1]), ctrl_row)
    affine = model.actuator_biastype == int(mujoco.mjtBias.mjBIAS_AFFINE)
    bias = np.where(affine, model.actuator_biasprm[:, 0] + model.actuator_biasprm[:, 1] * data.actuator_length
                    + model.actuator_biasprm[:, 2] * data.actuator_velocity, 0.0)
    f = model.actuator_gainprm[:, 0] * c + bias
    return np.where(model.actuator_forcelimited, np.clip(f, model.actuator_forcerange[:, 0],
                                                         model.actuator_forcerange[:, 1]), f)


def run_model(imported: ImportedModel, options: ModelOptions | None = None) -> EngineResult:
    """Step the user's model (with ``options``, default as written) over the scene's horizon.

    Raises
    ------
    ValueError
        A run of more than MAX_STEPS steps.
    NumericalFailure
        UNSTABLE: MuJoCo reset the state (a NaN, infinite or huge qpos, qvel or qacc): the run stops
        at that step, and the message gives the warning and its time; or MuJoCo found the mass
        matrix singular. CONTACT: two geoms touched (an active contact of MuJoCo's, checked at
        every step): the run stops there, and the message names both geoms, the time and the
        distance. NON_FINITE: the state became NaN or infinite. MuJoCo's other warnings (a
        buffer too small and the like) are logged on the ``loopcheck.mujoco`` logger, not fatal
        (:mod:`loopcheck.mujoco_model.warning_handler`).
    """
    options = options or ModelOptions.as_written(imported.model)
    scene = imported.scene
    h = options.timestep
    n = options.steps(scene.horizon)
    if n > MAX_STEPS:
        raise ValueError(f"a run of the model at timestep {h:g} s over simulation.horizon {scene.horizon:g} s is "
                         f"{n:.3g} steps, more than {MAX_STEPS:.3g}: raise the timestep or shorten --horizon")
    model = _configured(imported, options)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = imported.qpos, imported.qvel
    connects = [e for e in range(model.neq) if int(model.eq_type[e]) == _CONNECT]
    times = np.arange(n + 1) * h
    # every control, held over a step: the input motor's, and each scene actuator's (its own control over time)
    mid = times[:-1] + 0.5 * h
    ctrl = np.zeros((n, model.nu)) if model.nu else None
    if imported.control is not None:
        ctrl[:, imported.motor_index] = imported.control.at(mid)
    for a, actuator in zip(imported.actuator_index, scene.mechanism.actuators):
        if actuator.control is not None:
            ctrl[:, a] = actuator.control.sample(mid)
    qpos = np.empty((n + 1, model.nq))
    qvel = np.empty((n + 1, model.nv))
    qacc = np.empty((n + 1, model.nv))
    energy = np.empty((n + 1, 2))
    power = np.zeros((n + 1, 2))  # the actuators' (every one: qfrc_actuator sums them); the dampers', the dry friction's and the limits' (W)
    events = has_events(model)
    limits: dict[str, float] = {}  # each limit that acted, when it first did
    gap = np.empty(n + 1)

    # gravcomp's force, −gravcomp·m·g at each centre of mass, is conservative: its potential
    # +Σ gravcomp·m g·x_G joins MuJoCo's (mj_energyPos leaves it out); on a joint with
    # actuatorgravcomp MuJoCo adds it to qfrc_actuator, where the motor's work leaves it out
    compensated = model.body_gravcomp * model.body_mass
    routed = np.asarray(model.jnt_actgravcomp, dtype=float)[model.dof_jntid]

    shift = np.zeros(n + 1)  # the actuators' power at state k with the previous step's control, less that at state k

    def record(k: int) -> None:
        qpos[k], qvel[k], qacc[k], energy[k] = data.qpos, data.qvel, data.qacc, data.energy
        energy[k, 0] += float(compensated @ (data.xipos @ model.opt.gravity))
        power[k] = (float((data.qfrc_actuator - routed * data.qfrc_gravcomp) @ data.qvel),
                    float(-data.qfrc_damper @ data.qvel))
        if ctrl is not None and 0 < k < n:  # step k − 1 ended here under its own control
            shift[k] = float((_actuator_forces(model, data, ctrl[k - 1]) - _actuator_forces(model, data, ctrl[k]))
                             @ data.actuator_velocity)
        if events:
            power[k, 1] += friction_power(data)
            for element in active_limits(model, data):
                limits.setdefault(element, float(times[k]))
        gap[k] = _gaps(model, data, connects)

    contacts = not model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT) and model.ngeom > 0

    def touching(k: int) -> None:
        """Stop at the first contact (the exact reference has none)."""
        if contacts and data.ncon:
            found = first_contact(model, data)
            if found is not None:
                t = float(times[k])
                raise NumericalFailure(FailureReason.CONTACT, f"{found} at t = {t:.6g} s ({options.text()}): "
                                       "the exact reference has no contacts", t)

    start = time.perf_counter()
    with mujoco_warnings() as said:
        for k in range(n):
            if ctrl is not None:
                data.ctrl[:] = ctrl[k]
            mujoco.mj_forward(model, data)
            touching(k)
            record(k)
            mujoco.mj_step(model, data)
            bad = bad_state(data)
            if bad is not None:  # MuJoCo reset the state in this step: the run stops here
                t = float(times[k])
                raise NumericalFailure(FailureReason.UNSTABLE, bad.message(t, options.text()), t)
        mujoco.mj_forward(model, data)
        touching(n)
        record(n)
    singular = singular_mass_matrix(data, options.text())
    if singular is not None:
        raise NumericalFailure(FailureReason.UNSTABLE, singular)
    said.report(f"the model at {options.text()}")
    wall = time.perf_counter() - start
    bad = np.flatnonzero(~np.all(np.isfinite(qpos), axis=1))
    if len(bad):
        raise NumericalFailure(FailureReason.NON_FINITE, f"MuJoCo's state became NaN or infinite at "
                               f"t = {times[bad[0]]:.6g} s ({options.text()})", float(times[bad[0]]))

    system, T = loops.compile_linkage(scene.mechanism.linkage), imported.qpos_map
    x = imported.x_read + (qpos - imported.qpos) @ T.T
    xdot, xddot = qvel @ T.T, qacc @ T.T
    refine = samples_refine_extrema(model)
    trajectory = Trajectory(times, x @ system.drive, xdot @ system.drive, xddot @ system.drive, refine)
    # with several inputs, each after the first: q_i = row_i·x (the comparison judges every input)
    others = tuple(Trajectory(times, x @ row, xdot @ row, xddot @ row, refine) for row in system.input_rows[1:])
    joints = JointTrajectory(system.coordinate_names, times, x, xdot, np.full(n + 1, -1),
                             loops.assembly_modes(system, x))
    # the work of the actuators and the dampers' and dry friction's dissipation, by the trapezoidal rule
    # over each step (each step's control at both its ends: the actuators' power at a step's end is
    # taken with that step's control, not the next one's, so a control that jumps costs no O(h) error)
    work = np.zeros((n + 1, 2))
    work[1:] = np.cumsum(0.5 * h * (power[1:] + power[:-1]), axis=0)
    work[1:, 0] += np.cumsum(0.5 * h * shift[1:])
    audit = EnergyAudit(times, energy[:, 1], energy[:, 0], work[:, 0], work[:, 1])
    return EngineResult(engine=ENGINE, trajectory=trajectory, joints=joints, peak=trajectory.peak_rate(), audit=audit,
                        wall_s=wall, n_steps=n, n_evaluations=n * options.evaluations_per_step(), settings=options,
                        effects=tuple(scene.effects), constraint_violation=ConstraintViolation(times, gap),
                        details=ModelRunDetails(options, mujoco.__version__),
                        caveats=tuple(limit_note(e, t) for e, t in limits.items()),
                        other_inputs=tuple((other, other.peak_rate()) for other in others))


__all__ = ["ENGINE", "InputCoordinate", "MAX_STEPS", "MJCF_INTEGRATOR", "input_coordinate", "ModelOptions", "ModelRunDetails", "run_model"]
