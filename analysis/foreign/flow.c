/* flow.c - the steps of a user's model-exchange FMU, integrated in C (dfwb.foreign.native_flow binds it).
 *
 * The oracle is dfwb.foreign.flow with scipy's DOP853: this is the same method, stepped the same way
 * (scipy's step-size control, error norm and dense output, with scipy's coefficient tables passed in at
 * run time), and the same right-hand side: the FMU put at (t, x) with the input law
 *     u = F cos(omega_f t) - (C w + D y)      (an algebraic loop through a feedthrough: Flow._algebraic)
 * and dfwb's own states w riding along,
 *     w' = [A w + B y,  y cos(k omega t), y sin(k omega t) for k = 0..K,  u cos(omega t), u sin(omega t)]
 * (a controller's states, then a period's Fourier integrals; each part may be absent). The FMU's functions
 * are called straight from C: what Python paid per right-hand side (the wrappers, the arrays, scipy's
 * stages) was most of a user's FMU's time. Events, sections and every decision of a run stay in Python.
 *
 * Every loop is bounded: a step's stages (16), the algebraic rounds (max_algebraic), the step-size retries
 * (the step shrinks by at least a factor 0.9 (safety) until it is below 10 ulps of t).
 */
#include <math.h>
#include <stddef.h>

#if defined(__GNUC__) && !defined(_WIN32)
#define FLOW_API __attribute__((visibility("default")))
#else
#define FLOW_API
#endif

/* results */
enum { FLOW_OK = 0, FLOW_FMI = 1, FLOW_NOT_FINITE = 2, FLOW_ALGEBRAIC = 3, FLOW_TOO_SMALL = 4 };
/* the FMU's functions, in calls[] */
enum { SET_TIME, SET_STATES, SET_REAL, GET_REAL, GET_DERIVATIVES, CALLS };

typedef int (*set_time_f)(void *, double);
typedef int (*set_states_f)(void *, const double *, size_t);
typedef int (*get_array_f)(void *, double *, size_t);
typedef int (*real2_f)(void *, const unsigned int *, size_t, double *);
typedef int (*real3_f)(void *, const unsigned int *, size_t, double *, size_t);

typedef struct {
    void *component;
    void *calls[CALLS];
    int v3, nx, n, K, u_integrals, reads_output, max_algebraic;
    unsigned int input, output;
    double F, omega_f, D, omega, algebraic_tolerance; /* the last: ALGEBRAIC_ULPS ulps, relative */
    const double *A, *B, *C; /* n x n (rows), n, n */
    /* out: the last evaluation's output and input, counts, what failed */
    double y, u, at; /* at: the time of the last evaluation */
    long long evaluations;
    int failed_call, fmi_status;
} flow_model;

typedef struct {
    int n;                                  /* the length of z */
    double t, t_bound, t_old, h_abs, h_previous, rtol;
    const double *atol;                     /* n */
    double *y, *y_old, *f, *K, *work;       /* n, n, n, 16 n, 2 n */
    const double *A, *B, *C, *E3, *E5, *D;  /* scipy's tables: 16 x 16, 12, 16, 13, 13, 4 x 16 */
} flow_stepper;

#define STAGES 12
#define STAGES_EXTENDED 16

static int failed(flow_model *m, int call, int status)
{
    m->failed_call = call;
    m->fmi_status = status;
    return FLOW_FMI;
}

static int set_input(flow_model *m, double u)
{
    int status = m->v3 ? ((real3_f)m->calls[SET_REAL])(m->component, &m->input, 1, &u, 1)
                       : ((real2_f)m->calls[SET_REAL])(m->component, &m->input, 1, &u);
    return status > 1 ? failed(m, SET_REAL, status) : FLOW_OK;
}

static int get_output(flow_model *m, double *y)
{
    int status = m->v3 ? ((real3_f)m->calls[GET_REAL])(m->component, &m->output, 1, y, 1)
                       : ((real2_f)m->calls[GET_REAL])(m->component, &m->output, 1, y);
    return status > 1 ? failed(m, GET_REAL, status) : FLOW_OK;
}

static double law(const flow_model *m, double t, const double *w, double y)
{
    double cw = 0.0;
    for (int i = 0; i < m->n; i++)
        cw += m->C[i] * w[i];
    return m->F * cos(m->omega_f * t) - (cw + m->D * y);
}

/* The FMU at (t, z) with its input; the output and the input in m->y, m->u. */
static int evaluate(flow_model *m, double t, const double *z)
{
    const double *w = z + m->nx;
    double u = law(m, t, w, m->y), y;
    int status = ((set_time_f)m->calls[SET_TIME])(m->component, t);
    if (status > 1)
        return failed(m, SET_TIME, status);
    if (m->nx && (status = ((set_states_f)m->calls[SET_STATES])(m->component, z, (size_t)m->nx)) > 1)
        return failed(m, SET_STATES, status);
    if ((status = set_input(m, u)) || (status = get_output(m, &y)))
        return status;
    if (m->reads_output) { /* Flow._algebraic: a fixed-point round, then secant steps on law - u */
        double u_before = 0.0, g_before = 0.0;
        int round = 0, secant = 0;
        for (; round < m->max_algebraic; round++) {
            double following = law(m, t, w, y), g = following - u, ahead;
            if (fabs(g) <= m->algebraic_tolerance * fmax(fabs(u), fabs(following)))
                break;
            ahead = !secant || g == g_before ? following : u - g * (u - u_before) / (g - g_before);
            u_before = u;
            g_before = g;
            secant = 1;
            u = ahead;
            if ((status = set_input(m, u)) || (status = get_output(m, &y)))
                return status;
        }
        if (round == m->max_algebraic)
            return FLOW_ALGEBRAIC;
    }
    m->y = y;
    m->u = u;
    return FLOW_OK;
}

FLOW_API int dfwb_flow_rhs(flow_model *m, double t, const double *z, double *dz)
{
    m->evaluations++;
    m->at = t;
    int status = evaluate(m, t, z);
    if (status)
        return status;
    if (m->nx && (status = ((get_array_f)m->calls[GET_DERIVATIVES])(m->component, dz, (size_t)m->nx)) > 1)
        return failed(m, GET_DERIVATIVES, status);
    double sum = m->y + m->u;
    for (int i = 0; i < m->nx; i++)
        sum += dz[i];
    if (!isfinite(sum))
        return FLOW_NOT_FINITE;
    const double *w = z + m->nx;
    double *dw = dz + m->nx, y = m->y;
    for (int i = 0; i < m->n; i++) {
        double a = 0.0;
        for (int j = 0; j < m->n; j++)
            a += m->A[i * m->n + j] * w[j];
        dw[i] = a + m->B[i] * y;
    }
    if (m->K >= 0) {
        double *c = dw + m->n, *s = c + m->K + 1, wt = m->omega * t;
        for (int k = 0; k <= m->K; k++) {
            double phase = k * wt;
            c[k] = y * cos(phase);
            s[k] = y * sin(phase);
        }
        if (m->u_integrals) {
            s[m->K + 1] = m->u * cos(wt);
            s[m->K + 2] = m->u * sin(wt);
        }
    }
    return FLOW_OK;
}

/* z = y + h sum_{j<s} a_j K_j, scipy's order: the sum, then times h, then added */
static void stage_point(const flow_stepper *s, const double *y, const double *a, int stages, double h, double *z)
{
    for (int i = 0; i < s->n; i++) {
        double sum = 0.0;
        for (int j = 0; j < stages; j++)
            sum += s->K[j * s->n + i] * a[j];
        z[i] = y[i] + sum * h;
    }
}

/* One accepted step of DOP853 from (t, y), f = f(t, y): scipy's RungeKutta._step_impl. On FLOW_OK the
 * stepper holds the new t, y, f, h_abs (the next step's), t_old, y_old, h_previous and the stages K. */
FLOW_API int dfwb_flow_step(flow_model *m, flow_stepper *s)
{
    const int n = s->n;
    const double SAFETY = 0.9, MIN_FACTOR = 0.2, MAX_FACTOR = 10.0, EXPONENT = -1.0 / 8.0;
    double t = s->t, h_abs = s->h_abs, *z = s->work, *y_new = s->work + n;
    double min_step = 10.0 * fabs(nextafter(t, INFINITY) - t);
    int rejected = 0;
    if (h_abs < min_step)
        h_abs = min_step;
    for (;;) { /* bounded: a rejection shrinks h_abs by 0.9 at least, down to min_step */
        if (h_abs < min_step)
            return FLOW_TOO_SMALL;
        double t_new = t + h_abs;
        if (t_new - s->t_bound > 0.0)
            t_new = s->t_bound;
        double h = t_new - t;
        h_abs = fabs(h);
        for (int i = 0; i < n; i++)
            s->K[i] = s->f[i];
        int status;
        for (int stage = 1; stage < STAGES; stage++) {
            stage_point(s, s->y, s->A + stage * STAGES_EXTENDED, stage, h, z);
            if ((status = dfwb_flow_rhs(m, t + s->C[stage] * h, z, s->K + stage * n)))
                return status;
        }
        for (int i = 0; i < n; i++) {
            double sum = 0.0;
            for (int j = 0; j < STAGES; j++)
                sum += s->K[j * n + i] * s->B[j];
            y_new[i] = s->y[i] + h * sum;
        }
        if ((status = dfwb_flow_rhs(m, t + h, y_new, s->K + STAGES * n)))
            return status;
        double err5 = 0.0, err3 = 0.0;
        for (int i = 0; i < n; i++) {
            double scale = s->atol[i] + fmax(fabs(s->y[i]), fabs(y_new[i])) * s->rtol, e5 = 0.0, e3 = 0.0;
            for (int j = 0; j <= STAGES; j++) {
                e5 += s->K[j * n + i] * s->E5[j];
                e3 += s->K[j * n + i] * s->E3[j];
            }
            e5 /= scale;
            e3 /= scale;
            err5 += e5 * e5;
            err3 += e3 * e3;
        }
        double norm = (err5 == 0.0 && err3 == 0.0) ? 0.0 : h_abs * err5 / sqrt((err5 + 0.01 * err3) * n);
        if (norm < 1.0) {
            double factor = norm == 0.0 ? MAX_FACTOR : fmin(MAX_FACTOR, SAFETY * pow(norm, EXPONENT));
            if (rejected)
                factor = fmin(1.0, factor);
            s->h_abs = h_abs * factor;
            s->h_previous = h;
            s->t_old = t;
            s->t = t_new;
            for (int i = 0; i < n; i++) {
                s->y_old[i] = s->y[i];
                s->y[i] = y_new[i];
                s->f[i] = s->K[STAGES * n + i];
            }
            return FLOW_OK;
        }
        h_abs *= fmax(MIN_FACTOR, SAFETY * pow(norm, EXPONENT));
        rejected = 1;
    }
}

/* The last step's dense output (scipy's DOP853._dense_output_impl): its 7 x n coefficients into F. */
FLOW_API int dfwb_flow_dense(flow_model *m, flow_stepper *s, double *F)
{
    const int n = s->n;
    double h = s->h_previous, *z = s->work;
    int status;
    for (int stage = STAGES + 1; stage < STAGES_EXTENDED; stage++) {
        stage_point(s, s->y_old, s->A + stage * STAGES_EXTENDED, stage, h, z);
        if ((status = dfwb_flow_rhs(m, s->t_old + s->C[stage] * h, z, s->K + stage * n)))
            return status;
    }
    for (int i = 0; i < n; i++) {
        double delta = s->y[i] - s->y_old[i], f_old = s->K[i];
        F[i] = delta;
        F[n + i] = h * f_old - delta;
        F[2 * n + i] = 2 * delta - h * (s->f[i] + f_old);
        for (int r = 0; r < 4; r++) {
            double sum = 0.0;
            for (int j = 0; j < STAGES_EXTENDED; j++)
                sum += s->D[r * STAGES_EXTENDED + j] * s->K[j * n + i];
            F[(3 + r) * n + i] = h * sum;
        }
    }
    return FLOW_OK;
}
