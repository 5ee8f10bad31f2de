# C-level declaration of loopcheck/reduced/kernels/physics.py (Cython's augmenting .pxd).

from loopcheck.kernels.loops cimport Loops
from loopcheck.reduced.kernels.problem cimport RightHandSide

# The integer constants of the packed layout (physics.py documents them; its block
# `if not cython.compiled` holds the same values for plain Python: keep both in step,
# tests/test_physics_port.py compares them). A # The linkage's kinematics come first in I (loopcheck/kernels/loops.pxd: N, ..., the term tables,
# KIN_HEADER entries); this model's header follows.
cpdef enum:
    N_DAMPERS = 33
    N_ELEMENTS = 34
    N_FORCES = 35
    HAS_GRAVITY = 36
    DRIVE = 37
    MASSES = 38
    INERTIAS = 39
    GRAVITY = 40
    ELEMENT_COEF = 41
    ELEMENT_REST = 42
    FORCE_DIR = 43
    SPLINE_KNOTS = 44
    SPLINE_COEF = 45
    SPLINE_LO = 46
    SPLINE_HI = 47
    SPLINE_PERIOD = 48
    KNOT_START = 49
    COEF_START = 50
    SPLINE_DEGREE = 51
    DYAD_PLAN = 52
    DYAD_STEPS = 53
    DYAD_W = 54
    N_JOINT_ELEMENTS = 55
    N_JOINT_DAMPERS = 56
    JOINT_ROWS = 57
    JOINT_COEF = 58
    JOINT_REST = 59
    N_TIMED = 60
    TIMED_DIR = 61
    PIECE_VALUES = 62
    CENTRES = 1
    ENDS = 2
    FORCE_POINTS = 3
    N_JOINT_INERTIAS = 63
    N_ACTUATORS = 64
    ACT_ROWS = 65
    ACT_PARAMS = 66
    ACT_PIECE = 67
    N_CLAMPED = 68
    N_FRICTION = 72
    FRICTION_ROWS = 73
    FRICTION_COEF = 74
    N_RANGES = 75
    RANGE_ROWS = 76
    RANGE_BOUNDS = 77
    HEADER = 80
    INDEPENDENT = 0
    SIGN = 1
    STATUS = 2
    VALID = 3
    S_HEADER = 4
    OK = 0
    SINGULAR = 1
    WORK_SPENT = 2
    INERTIA = 0
    CENTRIFUGAL = 1
    POTENTIAL_GRADIENT = 2
    DAMPING = 3
    POTENTIAL = 4
    INPUT_RATE = 5
    POINT_FORCE = 6
    INPUT_CURVATURE = 7
    CONDITIONING = 8
    BEST_CONDITIONING = 9
    BEST = 10
    DETERMINANT = 11
    ACTUATOR_FIELD_A = 12
    ACTUATOR_FIELD_B = 13
    FRICTION_CAPACITY = 14
    FRICTION_MODE = 15
    N_FIELDS = 16
    STICK = 2
    SWITCH_EVENT = 0
    FRICTION_EVENT = 1
    RANGE_EVENT = 2
    CLAMP_FREE = 0
    CLAMP_HI = 1
    CLAMP_LO = -1
    CLAMP_AUTO = 2
    DEPTH = 32

cdef double _c_newton_tol, _c_newton_round_off, _c_predictor_trust
cdef double _c_trusted_correction, _c_long_jump, _c_far_jump, _c_hysteresis, _c_dyad_round_off
cdef double _c_kink_root
cdef double _c_closed_form_residual, _c_closed_form_reach, _c_pi, _c_nan, _c_clamp_hysteresis
cdef Py_ssize_t _c_newton_max_iter, _c_max_walk_closures
cdef long long _c_max_halvings

cdef double _nearest(double angle, double target)
cpdef bint _dyads(double[::1] F, long long[::1] I, Py_ssize_t first, double[::1] x, double[::1] base,
                  double[:, ::1] trig, Py_ssize_t i)


cdef class Chart(RightHandSide):
    cdef readonly object model, S, W
    cdef double[::1] F
    cdef long long[::1] I
    cdef readonly Py_ssize_t n
    # below this conditioning a coordinate cannot drive the linkage (passed in: Chart.__init__)
    cdef readonly double singular
    # the load piece of the latest acceleration: the piece stop_margin's stick test reads
    cdef readonly Py_ssize_t piece
    # the linkage's kinematics (loopcheck/kernels/loops.py), and its scratch under the names the
    # methods use (x, trig, A, rhs, norms, rows, kin and its rows K, L: views of loops.B)
    cdef readonly Loops loops
    # views of S and of W (physics.py: Chart), made once at construction
    cdef long long[::1] s, budget
    cdef double[::1] value, fields, rhs, norms, x, guess, target, spline, K, L, clamp, dyad_sides
    cdef double[:, ::1] origin, last, kin, A, trig, rows, marked
    # the sign of each joint friction's K_u = row·K watched for its kink (0: not watched): set_kinks
    cdef readonly double[::1] kinks
    cdef double[:, :, ::1] base

    cdef int _dyad_sides(self, Py_ssize_t first) except -1
    cdef int _dyads(self, Py_ssize_t first, Py_ssize_t i) except -1
    cdef int _finish(self, double det) except -1
    cdef int _close(self, Py_ssize_t depth, double value, double reach) except -1
    cdef int _walk(self, double value) except -1
    cdef double _point_force(self, Py_ssize_t p, double q) except? -1
    cdef int _coefficients(self) except -1
    cdef double _applied(self, Py_ssize_t piece) except? -1
    cdef double _unclamped(self, Py_ssize_t a, Py_ssize_t piece, double v) except? -1
    cdef bint _clamped(self, Py_ssize_t a) except -1
    cdef double _actuated(self, Py_ssize_t piece, double v, bint modes) except? -1
    cdef double _clamp_margin(self, Py_ssize_t a, double v) except? -1
    cdef double _friction_sign(self, double v) except? -2
    cdef double _event_margin(self, Py_ssize_t event, double v) except? -1
    cpdef bint evaluate(self, double value) except -1
    cpdef double acceleration(self, Py_ssize_t load, double t, double q, double v)
    cpdef double power(self, Py_ssize_t load, double v)
    cpdef double dissipation(self, double v)
    cpdef double stop_margin(self, double t, double q, double v)
    cpdef bint locate(self, double t, double q, double v)
    cpdef bint stop_at_start(self, double t, double q, double v)
    cpdef Py_ssize_t fired(self, double t, double q, double v)
    cpdef double rest_force(self, Py_ssize_t load, double q)
    cpdef set_friction(self, double mode)
    cpdef set_kinks(self, Py_ssize_t flipped)
    cpdef Py_ssize_t set_clamps(self, Py_ssize_t load, double q, double v)
    cpdef Py_ssize_t clamp_event(self, Py_ssize_t event)
    cpdef Py_ssize_t observation_size(self)
    cpdef observe(self, double[:, ::1] out, Py_ssize_t row)
    cpdef mark(self)
    cpdef rewind(self)
    cpdef reset(self)
    cpdef bint kinematics_at(self, double[::1] x, double[::1] row)
    cpdef bint start(self, double[::1] x, Py_ssize_t independent)
    cpdef Py_ssize_t walk(self, double[::1] values, double[:, ::1] fields, double[:, :, ::1] kin)
