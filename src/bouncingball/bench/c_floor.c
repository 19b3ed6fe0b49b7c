/* The floor of the compiled engine's cost: its CVODE work on one scene, in C, with no Python between phases.
 *
 * A benchmark-only copy of what simulate_cvode does with engine "compiled" at a constant F_ext:
 * the same SUNDIALS (scikit-sundae's wheel, reached through the function pointers of struct sundials,
 * whose prototypes c_floor.py generates from solvers/engines/compiled.py's checked declarations), the same
 * CVODE settings per mode, the same scaled gap state and root functions, a re-init at each event, the
 * same event polish on the mode's exact flow, the rest on the contact's exact flow, and the grid filled
 * from the step ends. Paths the article never takes (an event or rest decided in closed form by a
 * search, an over-damped contact) are refused with a message, never approximated.
 * Build with -ffp-contract=off -fno-builtin: the arithmetic must round as Python's does.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "c_floor_sundials.h"

enum { FLIGHT = 0, CONTACT = 1, IMPACT = 0, DEPARTURE = 1 };
enum { CV_SUCCESS = 0, CV_ROOT_RETURN = 2, CV_ONE_STEP = 2, NUM_ROOTS = 3, SERIES_TERMS = 24 };
#define EPS 2.220446049250313e-16 /* 2^-52 */
#define SERIES_REACH 0.5

/* What c_floor.py passes: the scene and every setting, named as in solvers/ (settings, phases, integrator) and compiled.py. */
struct floor_settings {
    double m, k, b, R, g, F_ext, h0, v0, t0;
    double rtol, atol; /* atol <= 0: none */
    double max_step, own_side, hop_resolution, soft_contact_cap, min_phase_scale, error_within_phase, estimate_safety;
    long max_num_steps, max_steps_per_phase;
    int method[2], max_order[2], max_nonlin_iters, max_conv_fails;
};

/* What the callbacks read: user_data of one mode's CVODE. */
struct phase {
    const struct sundials *S;
    double m, k, b, load, own_side, length, speed, hop, jacobian[4];
    int mode;
    long evaluations, max_evaluations;
};

struct solver {
    struct phase p;
    SUNContext context;
    N_Vector vector;
    SUNMatrix matrix;
    SUNLinearSolver linear_solver;
    void *memory;
    double *state;
};

struct points { double *t, *x, *v; int *mode; long n, size; };

struct run {
    const struct floor_settings *c;
    const struct sundials *S;
    struct solver solvers[2];
    struct points p;
    double t, x, v, load, g_eff, hop;
    double t_low; /* the rounding error of an event time t (machine.later); 0 elsewhere */
    /* the error estimate (error_estimate.py): the phase's start, the error of (x, v) there, the bound before it */
    double start_t, start_t_low, start_x, start_v, error_x, error_v, error_bound;
    int mode;
    long steps, rhs_calls;
    char *message;
    long message_size;
};

/* --- physics (equations.py) ----------------------------------------------------------------------- */
static double gap_acceleration(double x, double v, int mode, double load, double m, double k, double b) {
    if (mode == FLIGHT) return -load / m;
    return (-b * v - k * x - load) / m;
}

static double rest_margin_value(double x, double v, double d, double hop, double w2) {
    return w2 * (2.0 * d * hop - x * (x + 2.0 * d)) - v * v;
}

static double load_value(double F_ext, double m, double g) { /* Dekker's two-product, as equations.load_value */
    double product = m * g, split_m = 134217729.0 * m, split_g = 134217729.0 * g;
    if (!(fabs(split_m) < 1e300 && fabs(split_g) < 1e300 && fabs(product) < 1e300)) return product - F_ext;
    double m_high = split_m - (split_m - m), g_high = split_g - (split_g - g);
    double m_low = m - m_high, g_low = g - g_high;
    double error = ((m_high * g_high - product) + m_high * g_low + m_low * g_high) + m_low * g_low;
    return (product - F_ext) + error;
}

/* sqrt(x^2 + y^2) rounded as Python's math.hypot (nearly always the correctly rounded value; glibc's hypot
 * is 1 ulp off at times, which moved a contact's scale and so its steps): the sum of squares in two doubles,
 * its square root, and one Newton correction from the exact residual. */
static double hypot_rounded(double x, double y) {
    double a = fmax(fabs(x), fabs(y)), b = fmin(fabs(x), fabs(y));
    if (a == 0.0 || isinf(a)) return a;
    int exponent;
    frexp(a, &exponent);
    a = ldexp(a, -exponent), b = ldexp(b, -exponent); /* exact: a in [0.5, 1) */
    double aa = a * a, bb = b * b, sum = aa + bb;
    double low = (fma(a, a, -aa) + fma(b, b, -bb)) + (bb - (sum - aa)); /* sum + low = a^2 + b^2 */
    double h = sqrt(sum + low), hh = h * h;
    double residual = ((sum - hh) - fma(h, h, -hh)) + low;
    return ldexp(h + residual / (2.0 * h), exponent);
}

static void basis(double sigma, double w2, double tau, double *c, double *s) { /* under-damped only */
    double omega = sqrt(-(sigma * sigma - w2)), decay = exp(-sigma * tau);
    *c = decay * cos(omega * tau);
    *s = decay * sin(omega * tau) / omega;
}

/* c, s: basis(sigma, w2, tau), which the closed form reuses. */
static double unit_response(double sigma, double w2, double tau, double c, double s) {
    if ((sigma + sqrt(w2)) * fabs(tau) <= SERIES_REACH) {
        double before = 0.5 * tau * tau, term = -sigma * tau * tau * tau / 3.0, total = before + term;
        for (int n = 2; n < SERIES_TERMS; n++) {
            double next = (-2.0 * sigma * tau * (double)(n + 1) * term - w2 * tau * tau * before)
                          / (double)((n + 2) * (n + 1));
            before = term;
            term = next;
            total = total + term;
        }
        return total;
    }
    return (1.0 - c - sigma * s) / w2;
}

/* The mode's exact flow of the gap x = h - R and v over tau (Ball.gap_flow). */
static void gap_flow(const struct run *r, int mode, double x0, double v0, double tau, double *x, double *v) {
    const struct floor_settings *c = r->c;
    if (mode == FLIGHT) {
        *x = x0 + tau * (v0 - 0.5 * r->g_eff * tau);
        *v = v0 - r->g_eff * tau;
        return;
    }
    double sigma = c->b / (2.0 * c->m), w2 = c->k / c->m, cc, s, p;
    basis(sigma, w2, tau, &cc, &s);
    p = unit_response(sigma, w2, tau, cc, s);
    *x = x0 * cc + (v0 + sigma * x0) * s - r->g_eff * p;
    *v = v0 * cc - (sigma * v0 + w2 * x0) * s - r->g_eff * s;
}

/* The phase's flow with no load: the transition matrix's columns (error_estimate.phase_error). */
static void unit_flow(const struct run *r, int mode, double x0, double v0, double tau, double *x, double *v) {
    const struct floor_settings *c = r->c;
    if (mode == FLIGHT) {
        *x = x0 + tau * v0, *v = v0;
        return;
    }
    double sigma = c->b / (2.0 * c->m), w2 = c->k / c->m, cc, s;
    basis(sigma, w2, tau, &cc, &s);
    *x = x0 * cc + (v0 + sigma * x0) * s;
    *v = v0 * cc - (sigma * v0 + w2 * x0) * s;
}

/* The phase since (start_*) ends at the run's state: its error carried through the field's jump there
 * (error_estimate.carry_error), and the next phase starts (length: the phase's length scale). */
static void carry_error(struct run *r, int mode, double length, double jump) {
    const struct floor_settings *c = r->c;
    double tau = (r->t - r->start_t) + (r->t_low - r->start_t_low), x_flow, v_flow, p00, p10, p01, p11;
    gap_flow(r, mode, r->start_x, r->start_v, tau, &x_flow, &v_flow);
    unit_flow(r, mode, 1.0, 0.0, tau, &p00, &p10);
    unit_flow(r, mode, 0.0, 1.0, tau, &p01, &p11);
    double ex = p00 * r->error_x + p01 * r->error_v + (r->x - x_flow);
    double ev = p10 * r->error_x + p11 * r->error_v + (r->v - v_flow);
    double own = c->error_within_phase * c->rtol * length + 8.0 * EPS * (fabs(r->start_x) + length + c->R), carried;
    if (mode == FLIGHT) {
        carried = fmax(fabs(r->error_x), fabs(ex));
    } else {
        carried = fmax(hypot(r->error_x, r->error_v / sqrt(c->k / c->m)), fabs(ex));
        own += r->hop;
    }
    r->error_bound = fmax(r->error_bound, c->estimate_safety * (carried + own));
    r->error_x = ex, r->error_v = ev + jump * ex;
    r->start_t = r->t, r->start_t_low = r->t_low, r->start_x = r->x, r->start_v = r->v;
}

/* --- the callbacks (compiled.py's _rhs, _roots, _jacobian) ----------------------------------------- */
static int rhs(sunrealtype t, N_Vector y, N_Vector ydot, void *user_data) {
    struct phase *p = user_data;
    double *state = p->S->N_VGetArrayPointer(y), *out = p->S->N_VGetArrayPointer(ydot);
    out[0] = (p->speed / p->length) * state[1];
    out[1] = gap_acceleration(p->length * state[0], p->speed * state[1], p->mode, p->load, p->m, p->k, p->b)
             / p->speed;
    return 0;
}

static int roots(sunrealtype t, N_Vector y, sunrealtype *out, void *user_data) {
    struct phase *p = user_data;
    double *state = p->S->N_VGetArrayPointer(y), d = p->load / p->k;
    out[0] = state[0] != 0.0 ? state[0] : p->own_side;
    out[1] = (p->mode == CONTACT || p->load != 0.0) ? state[1] : 1.0;
    out[2] = (p->mode == CONTACT && d > 0.0)
                 ? rest_margin_value(p->length * state[0], p->speed * state[1], d, p->hop, p->k / p->m) : -1.0;
    return ++p->evaluations > p->max_evaluations ? 1 : 0;
}

static int jacobian(sunrealtype t, N_Vector y, N_Vector fy, SUNMatrix J, void *user_data, N_Vector tmp1,
                    N_Vector tmp2, N_Vector tmp3) {
    struct phase *p = user_data;
    sunrealtype **columns = p->S->SUNDenseMatrix_Cols(J);
    columns[0][0] = p->jacobian[0], columns[0][1] = p->jacobian[2];
    columns[1][0] = p->jacobian[1], columns[1][1] = p->jacobian[3];
    return 0;
}

/* --- errors, points ------------------------------------------------------------------------------- */
static int fail(struct run *r, int code, const char *what, double t) {
    snprintf(r->message, (size_t)r->message_size, "%s (t = %.17g s)", what, t);
    return code;
}

static int record(struct run *r, double t, double x, double v, int mode) {
    struct points *p = &r->p;
    if (p->n == p->size) {
        long size = p->size ? 2 * p->size : 4096;
        double *ts = realloc(p->t, size * sizeof *ts);
        if (ts) p->t = ts;
        double *xs = realloc(p->x, size * sizeof *xs);
        if (xs) p->x = xs;
        double *vs = realloc(p->v, size * sizeof *vs);
        if (vs) p->v = vs;
        int *modes = realloc(p->mode, size * sizeof *modes);
        if (modes) p->mode = modes;
        if (!(ts && xs && vs && modes)) return -1;
        p->size = size;
    }
    p->t[p->n] = t, p->x[p->n] = x, p->v[p->n] = v, p->mode[p->n] = mode;
    p->n++;
    r->t = t, r->x = x, r->v = v;
    return 0;
}

/* --- CVODE for one mode (compiled.PhaseSolver) ----------------------------------------------------- */
static int setup(struct run *r, struct solver *s, double t0, double y0, double y1) {
    const struct sundials *S = r->S;
    const struct floor_settings *c = r->c;
    int method = c->method[s->p.mode];
    if (S->SUNContext_Create(0, &s->context) < 0 || S->SUNContext_ClearErrHandlers(s->context) < 0) return -1;
    if (!(s->vector = S->N_VNew_Serial(2, s->context))) return -1;
    s->state = S->N_VGetArrayPointer(s->vector);
    s->state[0] = y0, s->state[1] = y1;
    if (!(s->matrix = S->SUNDenseMatrix(2, 2, s->context))) return -1;
    if (!(s->linear_solver = S->SUNLinSol_Dense(s->vector, s->matrix, s->context))) return -1;
    if (!(s->memory = S->CVodeCreate(method, s->context))) return -1;
    int directions[NUM_ROOTS] = {s->p.mode == FLIGHT ? -1 : 1, 0, 1};
    void *m = s->memory;
    if (S->CVodeSetUserData(m, &s->p) < 0 || S->CVodeInit(m, rhs, t0, s->vector) < 0
        || S->CVodeSStolerances(m, c->rtol, c->rtol) < 0 || S->CVodeSetLinearSolver(m, s->linear_solver, s->matrix) < 0
        || S->CVodeSetJacFn(m, jacobian) < 0 || S->CVodeSetMaxNonlinIters(m, c->max_nonlin_iters) < 0
        || S->CVodeSetMaxConvFails(m, c->max_conv_fails) < 0 || S->CVodeRootInit(m, NUM_ROOTS, roots) < 0
        || S->CVodeSetRootDirection(m, directions) < 0 || S->CVodeSetInitStep(m, 0.0) < 0
        || S->CVodeSetMinStep(m, 0.0) < 0 || S->CVodeSetMaxStep(m, c->max_step) < 0
        || S->CVodeSetMaxOrd(m, c->max_order[s->p.mode]) < 0 || S->CVodeSetMaxNumSteps(m, c->max_num_steps) < 0)
        return -1;
    return 0;
}

static void free_solver(const struct sundials *S, struct solver *s) {
    if (s->memory) S->CVodeFree(&s->memory);
    if (s->linear_solver) S->SUNLinSolFree(s->linear_solver);
    if (s->matrix) S->SUNMatDestroy(s->matrix);
    if (s->vector) S->N_VDestroy(s->vector);
    if (s->context) S->SUNContext_Free(&s->context);
}

/* --- the phase logic (solvers/integrator.py and phases.py) --------------------------------------------------- */
static void phase_scales(const struct run *r, int mode, double x, double v, double *length, double *speed) {
    const struct floor_settings *c = r->c;
    if (mode == FLIGHT) {
        if (r->g_eff > 0.0) {
            double up = v > 0.0 ? v : 0.0;
            double rise = up / sqrt(r->g_eff);
            *length = (x > 0.0 ? x : 0.0) + 0.5 * (rise * rise);
            *speed = sqrt(2.0 * r->g_eff * *length);
            return;
        }
        *length = fmax(fabs(x), c->R);
        *speed = fmax(fmax(fabs(v), sqrt(2.0 * fabs(r->g_eff) * *length)), *length);
        return;
    }
    double w = sqrt(c->k / c->m), d = r->load / c->k;
    double amplitude = hypot_rounded(x + d, v / w), cap = c->soft_contact_cap * fmax(c->R, fabs(x));
    *length = amplitude < cap ? amplitude : cap;
    *speed = w * *length;
}

static int contact_unresolved(const struct run *r) {
    double length, speed;
    phase_scales(r, CONTACT, r->x, r->v, &length, &speed);
    if (!(length >= r->c->min_phase_scale && speed > 0.0)) return 1;
    return fabs(r->load / r->c->k) < r->c->hop_resolution * r->c->rtol * length;
}

/* 1: at rest; 0: not; -1: only a search on the exact flow can tell (refused). */
static int at_rest(const struct run *r) {
    const struct floor_settings *c = r->c;
    if (r->mode != CONTACT) return 0;
    double d = r->load / c->k;
    if (d > 0.0 && rest_margin_value(r->x, r->v, d, r->hop, c->k / c->m) > 0.0) return 1;
    int undecided = c->b / (2.0 * sqrt(c->k * c->m)) >= 1.0 || d <= 0.0 || contact_unresolved(r);
    return undecided ? -1 : 0;
}

/* 1: the phase's event is in closed form (refused: not the article's), 0: CVODE integrates it. */
static int event_in_closed_form(const struct run *r) {
    if (r->mode == CONTACT) return r->load / r->c->k < 0.0 || contact_unresolved(r);
    if (r->x < 0.0 || !(r->g_eff > 0.0)) return 0;
    double apex, speed;
    phase_scales(r, FLIGHT, r->x, r->v, &apex, &speed);
    return apex < fmax(r->hop, r->c->min_phase_scale);
}

static int close_enough(struct run *r, double t_target) {
    double dt = t_target - r->t, a = fmax(fmax(fabs(t_target), fabs(r->t)), 1e-300);
    if (dt > 32.0 * (nextafter(a, INFINITY) - a)) return 0;
    double acceleration = gap_acceleration(r->x, r->v, r->mode, r->load, r->c->m, r->c->k, r->c->b);
    r->x = r->x + dt * (r->v + 0.5 * dt * acceleration);
    r->v = r->v + dt * acceleration;
    r->t = t_target, r->t_low = 0.0;
    return 1;
}

/* (t + t_low) + tau as a double, and its rounding error in *low (machine.later). */
static double later(double t, double t_low, double tau, double *low) {
    double total = t + tau, tau_part = total - t;
    double error = ((t - (total - tau_part)) + (tau - tau_part)) + t_low;
    double t_event = total + error;
    *low = error - (t_event - total);
    return t_event;
}

/* The crossing of x = 0 CVODE located at (tau, x, v): Newton on the exact flow (phases.polish_event); the speed
 * -v_start where the phase started on R at (x_start, v_start) and conserves it (contact_laws.conserved_speed). */
static void polish(const struct run *r, double length, double tau_before, double *tau_root, double x_root,
                   double *v_root, double x_start, double v_start) {
    double tau = 0.0, x = x_root, v = *v_root, v0 = *v_root;
    for (int i = 0; i < 8; i++) {
        if (x == 0.0 || v == 0.0) break;
        double correction = x / v;
        tau -= correction;
        gap_flow(r, r->mode, x_root, v0, tau, &x, &v);
        if (fabs(correction) <= 2.0 * EPS * fabs(*tau_root + tau)) break;
    }
    if (fabs(x) <= 16.0 * EPS * length && *tau_root + tau >= tau_before) *tau_root = *tau_root + tau, *v_root = v;
    if (x_start == 0.0 && (r->mode == FLIGHT ? v_start > 0.0 : v_start < 0.0 && r->c->b == 0.0)) *v_root = -v_start;
    if (r->mode == FLIGHT ? *v_root > 0.0 : *v_root < 0.0) *v_root = 0.0;
}

static int check_side(struct run *r, double t, double x, double length) {
    double margin = fmax(r->hop, r->c->hop_resolution * r->c->rtol * length);
    if (r->mode == FLIGHT ? x < -margin : x > margin)
        return fail(r, -3, "CVODE stepped over an event unseen", t);
    return 0;
}

/* One phase integrated by CVODE from the current state to a terminal root or t_end. */
static int integrate_phase(struct run *r, double t_end, int *resting, double *events, long max_events,
                           long *n_events) {
    const struct sundials *S = r->S;
    const struct floor_settings *c = r->c;
    struct solver *s = &r->solvers[r->mode];
    double origin = r->t, origin_low = r->t_low, t_low = 0.0, length, speed;
    phase_scales(r, r->mode, r->x, r->v, &length, &speed);
    if (c->atol > 0.0 && c->rtol * length > c->atol) {
        speed *= c->atol / (c->rtol * length);
        length = c->atol / c->rtol;
    }
    struct phase *p = &s->p;
    double j10 = r->mode == CONTACT ? -c->k / c->m : 0.0;
    p->length = length, p->speed = speed, p->hop = r->hop;
    p->jacobian[0] = 0.0, p->jacobian[1] = 1.0 * speed / length;
    p->jacobian[2] = j10 * length / speed, p->jacobian[3] = r->mode == CONTACT ? -c->b / c->m : 0.0;
    p->evaluations = 0;
    double y0 = r->x / length, y1 = r->v / speed, tau_end = t_end - origin;
    if (!s->memory) {
        if (setup(r, s, 0.0, y0, y1) < 0) return fail(r, -2, "CVODE's set-up failed", r->t);
    } else {
        s->state[0] = y0, s->state[1] = y1;
        if (S->CVodeReInit(s->memory, 0.0, s->vector) < 0) return fail(r, -2, "CVodeReInit failed", r->t);
    }
    if (S->CVodeSetStopTime(s->memory, tau_end) < 0) return fail(r, -2, "CVodeSetStopTime failed", r->t);
    long first = r->p.n;
    int mode = r->mode, flag, info[NUM_ROOTS] = {0, 0, 0};
    if (record(r, origin, r->x, r->v, mode) < 0) return fail(r, -4, "out of memory", r->t);
    double tau;
    for (;;) {
        flag = S->CVode(s->memory, tau_end, s->vector, &tau, CV_ONE_STEP);
        if (flag == CV_ROOT_RETURN) {
            if (S->CVodeGetRootInfo(s->memory, info) < 0) return fail(r, -2, "CVodeGetRootInfo failed", r->t);
            if (info[0] == 0 && info[2] == 0) continue;
        }
        if (flag < 0) return fail(r, flag, p->evaluations > p->max_evaluations
                                               ? "too many steps in one phase" : "CVode failed", origin + tau);
        if (record(r, origin + tau, length * s->state[0], speed * s->state[1], mode) < 0)
            return fail(r, -4, "out of memory", r->t);
        if (flag != CV_SUCCESS) break;
    }
    long rhs_calls;
    if (S->CVodeClearStopTime(s->memory) < 0 || S->CVodeGetNumRhsEvals(s->memory, &rhs_calls) < 0)
        return fail(r, -2, "CVodeClearStopTime or CVodeGetNumRhsEvals failed", r->t);
    int root = flag == CV_ROOT_RETURN && info[0] != 0;
    *resting = flag == CV_ROOT_RETURN && info[2] != 0;
    long last = r->p.n - 1;
    double *ts = r->p.t, *xs = r->p.x, *vs = r->p.v, extreme = xs[first];
    for (long i = first; i < (root ? last : last + 1); i++)
        extreme = mode == FLIGHT ? fmin(extreme, xs[i]) : fmax(extreme, xs[i]);
    if (root) {
        double tau_before = ts[last - 1] - origin, tau_root = tau, v_root = vs[last];
        polish(r, length, tau_before, &tau_root, xs[last], &v_root, xs[first], vs[first]);
        ts[last] = later(origin, origin_low, tau_root, &t_low), xs[last] = 0.0, vs[last] = v_root;
        if (check_side(r, origin + tau_before, extreme, length) < 0) return -3;
    } else if (check_side(r, ts[last], extreme, length) < 0) {
        return -3;
    }
    if (!(root || *resting)) ts[last] = t_end;
    r->t = ts[last], r->x = xs[last], r->v = vs[last], r->t_low = root ? t_low : 0.0;
    if (root) carry_error(r, mode, length, mode == FLIGHT ? -c->b / c->m : c->b / c->m);
    r->steps += last - first;
    r->rhs_calls += rhs_calls;
    if (root) {
        if (*n_events == max_events) return fail(r, -4, "more events than room for them", r->t);
        double *event = events + 3 * *n_events;
        event[0] = r->t, event[1] = mode == FLIGHT ? IMPACT : DEPARTURE, event[2] = r->v;
        ++*n_events;
        r->mode = mode == FLIGHT ? CONTACT : FLIGHT;
    }
    return 0;
}

/* x and v on the grid from the step ends (dense_output.interpolate): each mode's flow plus the end's mismatch. */
static void fill(const struct run *r, const double *grid, long n_grid, double *h, double *v) {
    const struct points *p = &r->p;
    long i = 0, a = -1;
    double dt = 0.0, x_end = 0.0, v_end = 0.0;
    for (long g = 0; g < n_grid; g++) {
        double t = grid[g], x, vv;
        while (i + 1 < p->n && p->t[i + 1] <= t) i++;
        if ((i < p->n - 2 ? i : p->n - 2) != a) { /* a new step: its flow to the end, once */
            a = i < p->n - 2 ? i : p->n - 2;
            dt = p->t[a + 1] - p->t[a];
            gap_flow(r, p->mode[a], p->x[a], p->v[a], dt, &x_end, &v_end);
        }
        double tau = t - p->t[a], s = dt > 0.0 ? tau / dt : 0.0;
        gap_flow(r, p->mode[a], p->x[a], p->v[a], tau, &x, &vv);
        h[g] = r->c->R + (x + s * (p->x[a + 1] - x_end));
        v[g] = vv + s * (p->v[a + 1] - v_end);
    }
}

static double now(void) {
    struct timespec time;
    clock_gettime(CLOCK_MONOTONIC, &time);
    return (double)time.tv_sec + 1e-9 * (double)time.tv_nsec;
}

/* The run: grid[0] is the start, grid[n_grid - 1] the end. Returns 0, or < 0 with message set.
 * counts receives the steps, right-hand-side calls and events; events (t, 0 impact or 1 departure, v);
 * seconds the wall time spent in here. */
int c_floor_run(const struct sundials *S, const struct floor_settings *c, const double *grid, long n_grid,
                double *h, double *v, double *events, long max_events, long *counts, double *seconds,
                double *error_estimate, char *message, long message_size) {
    double started = now();
    struct run r;
    memset(&r, 0, sizeof r);
    r.c = c, r.S = S, r.message = message, r.message_size = message_size;
    r.load = load_value(c->F_ext, c->m, c->g);
    r.g_eff = r.load / c->m;
    double d = r.load / c->k, t_end = grid[n_grid - 1];
    r.hop = (c->b == 0.0 || !(d > 0.0)) ? 0.0 : c->hop_resolution * c->rtol * d;
    if (c->atol > 0.0 && r.hop > c->hop_resolution * c->atol) r.hop = c->hop_resolution * c->atol;
    for (int mode = FLIGHT; mode <= CONTACT; mode++) {
        struct phase *p = &r.solvers[mode].p;
        p->S = S, p->m = c->m, p->k = c->k, p->b = c->b, p->load = r.load, p->mode = mode;
        p->own_side = mode == FLIGHT ? c->own_side : -c->own_side;
        p->max_evaluations = c->max_steps_per_phase;
    }
    r.t = c->t0, r.x = c->h0 - c->R, r.v = c->v0;
    r.start_t = r.t, r.start_x = r.x, r.start_v = r.v;
    double g_eff = r.g_eff;
    r.mode = (c->h0 < c->R || (c->h0 == c->R && (c->v0 < 0.0 || (c->v0 == 0.0 && g_eff > 0.0)))) ? CONTACT : FLIGHT;
    long n_events = 0;
    int status = record(&r, r.t, r.x, r.v, r.mode) < 0 ? fail(&r, -4, "out of memory", r.t) : 0, resting = 0;
    while (status == 0 && r.t < t_end && !close_enough(&r, t_end)) {
        int rest = resting ? 1 : at_rest(&r);
        if (rest < 0) {
            status = fail(&r, -5, "a rest only a search on the exact flow can decide: not the article's path", r.t);
        } else if (rest) {
            double x0 = r.x, v0 = r.v, x, vv;
            gap_flow(&r, CONTACT, x0, v0, t_end - r.t, &x, &vv);
            if (record(&r, r.t, x0, v0, r.mode) < 0 || record(&r, t_end, x, vv, r.mode) < 0)
                status = fail(&r, -4, "out of memory", r.t);
            break;
        } else if (event_in_closed_form(&r)) {
            status = fail(&r, -5, "an event in closed form: not the article's path", r.t);
        } else {
            status = integrate_phase(&r, t_end, &resting, events, max_events, &n_events);
        }
    }
    if (status == 0 && r.t > r.p.t[r.p.n - 1] && record(&r, r.t, r.x, r.v, r.mode) < 0)
        status = fail(&r, -4, "out of memory", r.t);
    if (status == 0) {
        double length, speed;
        phase_scales(&r, r.mode, r.start_x, r.start_v, &length, &speed);
        if (c->atol > 0.0 && c->rtol * length > c->atol) length = c->atol / c->rtol;
        carry_error(&r, r.mode, length, 0.0); /* the last phase, to t_end */
        fill(&r, grid, n_grid, h, v);
    }
    *error_estimate = r.error_bound;
    counts[0] = r.steps, counts[1] = r.rhs_calls, counts[2] = n_events;
    for (int mode = FLIGHT; mode <= CONTACT; mode++) free_solver(S, &r.solvers[mode]);
    free(r.p.t), free(r.p.x), free(r.p.v), free(r.p.mode);
    *seconds = now() - started;
    return status;
}
