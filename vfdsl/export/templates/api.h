/* @API@: the virtual fixture "@TASK@" (@SOURCE@) as a C library, written by `vfdsl export`.
 *
 * One controller per robot (or per thread):
 *
 *     @API@* ctrl = @API@_new();                      all allocation happens here (NULL: out of
 *                                                     memory, or @MAX@ controllers exist already)
 *     int s = @API@_step(ctrl, q, inputs, dt, dq);    each tick: dq = the joint increment to command
 *     if (s < 0) puts(@API@_error_message(s));        refused before anything moved: dq is zeros
 *     @API@_free(ctrl);
 *
 * Units are SI (m, rad, s, N, N m). q has @MACRO@_NUM_JOINTS entries; inputs holds every input in
 * declaration order, @MACRO@_INPUT_LENGTH numbers in all (see @API@_input_name/_size/_unit). The
 * arrays of the prototypes carry these sizes: a C compiler (GCC 11 or later) warns when a smaller
 * array is passed.
 *
 * @API@_step returns the status bits of the tick (>= 0: VF_OPTIMAL, or VF_LEAST_VIOLATION,
 * VF_BOUNDS_CLIPPED, VF_FALLBACK, VF_UNCERTIFIED set) or a negative VF_ERR_* code naming the argument it refuses; it
 * checks before anything moves what Python's Controller.step() checks: every number finite, each q_i
 * within its joint's limits widened by the joint's span on each side, dt within [@MIN_PERIOD@, @MAX_PERIOD@] s (the
 * task's range around its period: further is a unit slip, VF_ERR_DT_PERIOD).
 * @API@_set_param checks the params with the task's column of checks (zero and derived directions,
 * implausible points, lengths and angles, scalar ranges, run-time curve chords), the same code as
 * Python's, and keeps the previous values when it refuses them.
 *
 * Threads: controllers are independent and run in parallel threads. The calls on one controller
 * (_step, _set_param, _set_params, _violations, _error_index, _error_check) run one at a time: a
 * call that finds another one running on the same controller returns VF_ERR_BUSY at once and touches
 * nothing (dq zeros). The functions without a controller run in any thread at any time; _free must
 * not overlap another call on the same controller. After @API@_new, no call but @API@_free allocates
 * memory, takes a lock or makes a system call.
 */
#ifndef @GUARD@
#define @GUARD@

#ifdef __cplusplus
extern "C" {
#endif

#ifndef VFDSL_STATUS_AND_ERRORS
#define VFDSL_STATUS_AND_ERRORS
/* Status bits of a tick (a return value >= 0). */
#define VF_OPTIMAL 0             /* every hard row holds */
#define VF_LEAST_VIOLATION 1     /* the hard rows could not all hold: dq is the least-violation motion */
#define VF_BOUNDS_CLIPPED 2      /* q was outside its joint limits: dq returns toward them */
#define VF_FALLBACK 4            /* a solve failed numerically: dq is the rest motion */
#define VF_UNCERTIFIED 8         /* priority levels: no certificate that dq is their exact optimum (DAQP's answer,
                                    to its tolerance; at a least-violation tick, the least violation alone) */
/* Errors (a return value < 0): nothing moved, dq_out is zeros. */
#define VF_ERR_NULL (-1)         /* a pointer argument is NULL */
#define VF_ERR_Q_NONFINITE (-2)  /* q holds NaN or inf */
#define VF_ERR_Q_RANGE (-3)      /* q is far outside its joint limits (a unit mistake, a faulty encoder) */
#define VF_ERR_INPUT (-4)        /* inputs hold NaN or inf, or fail their type's checks */
#define VF_ERR_DT (-5)           /* dt is NaN, inf or <= 0 */
#define VF_ERR_PARAM_INDEX (-6)  /* no run-time param has this index */
#define VF_ERR_PARAM (-7)        /* a param value is NaN or inf, or fails a check */
#define VF_ERR_BUSY (-8)         /* another thread is inside a call on this controller */
#define VF_ERR_SOLVER (-9)       /* the generated step failed (should not happen; report it) */
#define VF_ERR_DT_PERIOD (-10)   /* dt is far from the task's period (a unit slip): outside [_min_period, _max_period] */
#define VF_ERR_NO_TELEOP (-11)   /* _teleop on a task without a teleop term */
#endif

/* The task's sizes, for arrays: double q[@MACRO@_NUM_JOINTS], inputs[@MACRO@_INPUT_LENGTH]. */
#define @MACRO@_NUM_JOINTS @NQ@     /* q and dq */
#define @MACRO@_INPUT_LENGTH @NU@   /* every input's numbers */
#define @MACRO@_NUM_INPUTS @NINPUTS@
#define @MACRO@_PARAM_LENGTH @NP@   /* every run-time param's numbers (_set_params) */
#define @MACRO@_NUM_PARAMS @NPARAMS@
#define @MACRO@_NUM_ROWS @ROWS@

typedef struct @API@ @API@;     /* one controller: opaque */

/* One violated constraint after a tick: a hard row's excess over its bound, or a soft constraint's
 * slack, in its unit. The strings are static. */
typedef struct {
  const char* label;       /* e.g. "stays_at(tip) facet 3/6 [tasks/paper_b.vf:18]" */
  const char* primitive;   /* e.g. "stays_at" */
  const char* file;        /* the .vf file of the constraint */
  int line;                /* its line there */
  const char* unit;        /* "m", "rad" or "" */
  double amount;
} @API@_violation;

@API@* @API@_new(void);
void @API@_free(@API@* ctrl);

/* inputs may be NULL when the task has none. */
int @API@_step(@API@* ctrl, const double q[@MACRO@_NUM_JOINTS], @INPUTS_ARGUMENT@, double dt,
               double dq_out[@MACRO@_NUM_JOINTS]);

/* Run-time param `index` (0 .. @API@_num_params() - 1) = values (@API@_param_size(index) numbers). 0, or
 * VF_ERR_PARAM_INDEX, VF_ERR_PARAM (see @API@_error_check), VF_ERR_NULL, VF_ERR_BUSY; a refused value
 * changes nothing. @API@_set_params sets all at once (@API@_param_length() numbers, in param order:
 * needed when a check involves several params, e.g. two points of a line). */
int @API@_set_param(@API@* ctrl, int index, const double* values);
int @API@_set_params(@API@* ctrl, @PARAMS_ARGUMENT@);
/* What the last error returned by a call on this controller is about (every error but VF_ERR_BUSY, which
 * touches nothing, and VF_ERR_NULL without a controller, sets both; a call that succeeds sets both to -1):
 * _error_index: the joint (VF_ERR_Q_*), the number in inputs (VF_ERR_INPUT), the param's index k of
 *   _param_name(k) (VF_ERR_PARAM: the param holding NaN or inf, or the param the failed check is about;
 *   -1 when the check is about a value derived from several params), the index given (VF_ERR_PARAM_INDEX);
 *   -1 otherwise.
 * _error_check: the task's check that failed (VF_ERR_PARAM), -1 otherwise (a NaN or inf value included).
 * Both return VF_ERR_BUSY while another call runs on the controller. */
int @API@_error_index(const @API@* ctrl);
int @API@_error_check(const @API@* ctrl);
/* What check `check` asks (e.g. "param 'axis' must not be a zero direction"); never NULL: for -1 or
 * any other number that is not a check, a sentence saying so. */
const char* @API@_check_meaning(int check);

/* After a tick: the violated constraints in row order (hard rows, then soft constraints); writes at most
 * `capacity` of them and returns how many there are, or VF_ERR_BUSY while another call runs on the
 * controller (nothing written). */
int @API@_violations(const @API@* ctrl, @API@_violation* out, int capacity);

/* The strings below are static and never NULL: an index out of range gives "". */
const char* @API@_error_message(int code);

int @API@_num_joints(void);
const char* @API@_joint_name(int i);
const char* @API@_joint_unit(int i);
double @API@_default_period(void);   /* the scene's period in s, or 0 when the task has none */
double @API@_min_period(void);      /* the shortest dt accepted, s */
double @API@_max_period(void);      /* the longest dt accepted, s */
const double* @API@_start(void);     /* the scene's start configuration (zeros when none): q of the priming */
int @API@_input_length(void);
int @API@_num_inputs(void);
const char* @API@_input_name(int k);
int @API@_input_size(int k);
const char* @API@_input_unit(int k);
int @API@_param_length(void);
int @API@_num_params(void);
const char* @API@_param_name(int k);
const char* @API@_param_type(int k);
int @API@_param_size(int k);
const char* @API@_param_unit(int k);
const double* @API@_param_default(int k);   /* @API@_param_size(k) numbers */
int @API@_num_rows(void);
const char* @API@_row_label(int i);

/* A procedure (a task with phases; without, these give 0 phases and -1): its machine runs in _step before the
 * solve (the same code as Python's native Controller). After a tick, _phase is the phase's index (its name:
 * _phase_name), _transition the index of the transition fired in it or -1 (its guard as written:
 * _transition_guard; _transition_source, -1 for '*', and _transition_target are phase indices), _monitor(ctrl,
 * i) 1 when named monitor i (_monitor_name) held, else 0. A negative VF_ERR_* for a NULL or busy controller.
 * _reset: back to the initial phase, its captures retaken at the next tick (the solver's warm start is kept). */
int @API@_phase(const @API@* ctrl);
int @API@_transition(const @API@* ctrl);
int @API@_monitor(const @API@* ctrl, int i);
int @API@_reset(@API@* ctrl);
int @API@_num_phases(void);
const char* @API@_phase_name(int i);
int @API@_num_monitors(void);
const char* @API@_monitor_name(int i);
int @API@_num_transitions(void);
const char* @API@_transition_guard(int k);
int @API@_transition_source(int k);
int @API@_transition_target(int k);

/* Teleoperation (a task with a `teleop` term, docs/language.md "Teleoperation"; _is_teleoperated says so): after
 * each tick, _teleop writes the haptic force for the master (N, in the master's base frame: what the fixtures
 * stopped of its command, stiffness x depth along their normals, saturated, rate-limited, ramped in at engage),
 * the teleop frame's set-point (its pose after dq: m, then roll, pitch, yaw in rad, for a robot driven by pose),
 * the goal (where the scaled master puts the frame, m), the master's depth past the rows that acted (m, its
 * base frame) and following (1 while the master drives the slave):
 * 0, VF_ERR_NULL, VF_ERR_BUSY, or VF_ERR_NO_TELEOP without a teleop term. _row_acting(ctrl, i): 1 when row i
 * (_row_label) was at its bound in the last tick, else 0 (always 0 without a teleop term). _reset also restarts
 * the readout (no previous depth or force). The same readout as Python's Controller.teleop, from the same code. */
typedef struct {
  double force[3];
  double setpoint[6];
  double goal[3];
  double depth[3];     /* how far the master is past the rows that acted (m, its base frame) */
  int following;
} @API@_teleop_readout;
int @API@_teleop(const @API@* ctrl, @API@_teleop_readout* out);
int @API@_row_acting(const @API@* ctrl, int i);
int @API@_is_teleoperated(void);

#ifdef __cplusplus
}
#endif
#endif
