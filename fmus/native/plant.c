/* plant.c - what the plants share: errors, the event log, states as bytes, the piece machinery of
 * fmus/piecewise.py (PiecewisePlant), and the API functions that are the same for every plant (see plant.h).
 *
 * The piece machinery keeps piecewise.py's operation order and bounds: the searches run lazily in chunks
 * of period/8 anchored at the piece's start, in the order they were added; a step spans at most
 * MAX_PERIODS_PER_STEP periods and fires at most MAX_EVENTS_PER_STEP events, and at most
 * EVENTS_PER_PERIOD_LIMIT * (1 + step/period).
 */
#include "plant.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dfwb_core.h"

/* -- errors ------------------------------------------------------------------------- */
void dfwb_err_init(dfwb_err *err, char *buf, size_t len)
{
    err->buf = buf;
    err->len = len;
    err->code = DFWB_OK;
    err->overflow = NULL;
    if (buf != NULL && len > 0)
        buf[0] = '\0';
}

int dfwb_err_finish(dfwb_err *err, int rc)
{
    if (err->overflow != NULL) {
        const char *message = err->overflow;
        err->code = DFWB_OK; /* the overflow came first: its message replaces a later refusal's */
        return dfwb_fail(err, DFWB_E_MATH, "%s", message);
    }
    return rc;
}

int dfwb_check(dfwb_err *err, const char *name, double value, int ok, const char *allowed)
{
    char r[DFWB_REPR_SIZE];
    if (isfinite(value) && ok)
        return DFWB_OK;
    dfwb_repr(value, r);
    return dfwb_fail(err, DFWB_E_VALUE, "%s = %s is out of range: %s", name, r, allowed);
}

int dfwb_check_drive(dfwb_err *err, double F, double omega, double phi, double f, double harmonics)
{
    int rc;
    if ((rc = dfwb_check(err, "F", F, 1, "F must be a finite number (N)")) != DFWB_OK
        || (rc = dfwb_check(err, "omega", omega, omega > 0.0, "omega must be > 0 (rad/s)")) != DFWB_OK
        || (rc = dfwb_check(err, "phi", phi, fabs(phi) <= DFWB_PHASE_LIMIT,
                            "phi must be in [-" DFWB_PHASE_LIMIT_TEXT ", " DFWB_PHASE_LIMIT_TEXT
                            "] rad (beyond, a float does not resolve a period)")) != DFWB_OK
        || (rc = dfwb_check(err, "f", f, 1, "the input f must be a finite number (N)")) != DFWB_OK)
        return rc;
    return dfwb_check(err, "harmonics", harmonics, floor(harmonics) == harmonics && 0.0 <= harmonics
                      && harmonics <= 10.0, "harmonics must be an integer in 0..10");
}

int dfwb_check_t_end(dfwb_err *err, double t, double t_end)
{
    char rt[DFWB_REPR_SIZE], allowed[96];
    if (isfinite(t_end) && t_end >= t)
        return DFWB_OK;
    dfwb_repr(t, rt);
    strcpy(allowed, "the end of a step must be >= the current time ");
    strcat(allowed, rt);
    return dfwb_check(err, "t_end", t_end, 0, allowed);
}

void dfwb_drive_values(const dfwb_drive *d, double out[4])
{
    out[0] = d->f;
    out[1] = d->F;
    out[2] = d->omega;
    out[3] = d->phi;
}

int dfwb_same_double(double a, double b) { return memcmp(&a, &b, sizeof a) == 0; }

/* -- names ---------------------------------------------------------------------------- */
const char *dfwb_event_name(int kind)
{
    switch (kind) {
    case DFWB_EVENT_BREAK_UP: return "break+";
    case DFWB_EVENT_BREAK_DOWN: return "break-";
    case DFWB_EVENT_RELEASE: return "release";
    case DFWB_EVENT_EDGE: return "edge";
    case DFWB_EVENT_BAND: return "band";
    case DFWB_EVENT_WALL_LOWER: return "gap 0";
    case DFWB_EVENT_WALL_UPPER: return "gap h";
    case DFWB_EVENT_APEX: return "apex";
    case DFWB_EVENT_ENGAGE_UP: return "engage+";
    case DFWB_EVENT_ENGAGE_DOWN: return "engage-";
    case DFWB_EVENT_REVERSE: return "reverse";
    case DFWB_EVENT_COULOMB: return "coulomb";
    case DFWB_EVENT_DEADBAND: return "deadband";
    default: return "None";
    }
}

const char *dfwb_plant_name(int kind)
{
#define DFWB_NAME_CASES(kind, name)                                                                                \
    case kind: return "dfwb_" #name;                                                                               \
    case DFWB_STATE_LOOP + kind: return "dfwb_" #name "_loop";
    switch (kind) {
        DFWB_PLANTS(DFWB_NAME_CASES)
    default: return "unknown plant";
    }
#undef DFWB_NAME_CASES
}

/* -- the event log -------------------------------------------------------------------- */
#define LOG_MAX (((size_t)-1) / 2 / sizeof(dfwb_log_entry))

void dfwb_log_enable(dfwb_log *log, size_t capacity)
{
    if (capacity > LOG_MAX)
        capacity = LOG_MAX;
    if (capacity == 0) {
        dfwb_log_free(log);
        return;
    }
    log->capacity = capacity;
    log->dropped = 0;
    if (log->n > capacity) { /* a smaller capacity keeps the oldest entries */
        log->dropped += log->n - capacity;
        log->n = capacity;
    }
}

void dfwb_log_add(dfwb_log *log, double t, int kind)
{
    if (log->capacity == 0)
        return;
    if (log->n >= log->capacity) {
        log->dropped += 1;
        return;
    }
    if (log->n == log->cap) {
        size_t cap = log->cap ? 2 * log->cap : 64;
        dfwb_log_entry *data;
        if (cap > log->capacity)
            cap = log->capacity;
        data = (dfwb_log_entry *)realloc(log->data, cap * sizeof *data);
        if (data == NULL) { /* the log never changes the solution: the event is counted as dropped */
            log->dropped += 1;
            return;
        }
        log->data = data;
        log->cap = cap;
    }
    log->data[log->n].t = t;
    log->data[log->n].kind = kind;
    log->n += 1;
}

size_t dfwb_log_read(dfwb_log *log, double *t, int *kind, size_t max)
{
    size_t i, n;
    if (t == NULL || kind == NULL || max == 0)
        return log->n;
    n = max < log->n ? max : log->n;
    for (i = 0; i < n; i++) {
        t[i] = log->data[i].t;
        kind[i] = log->data[i].kind;
    }
    if (n < log->n)
        memmove(log->data, log->data + n, (log->n - n) * sizeof *log->data);
    log->n -= n;
    return n;
}

int dfwb_log_copy(dfwb_log *dst, const dfwb_log *src)
{
    dst->data = NULL;
    dst->n = dst->cap = 0;
    dst->capacity = src->capacity;
    dst->dropped = src->dropped;
    if (src->n > 0) {
        dst->data = (dfwb_log_entry *)malloc(src->n * sizeof *dst->data);
        if (dst->data == NULL) {
            dst->capacity = 0;
            return 0;
        }
        memcpy(dst->data, src->data, src->n * sizeof *dst->data);
        dst->n = dst->cap = src->n;
    }
    return 1;
}

void dfwb_log_free(dfwb_log *log)
{
    free(log->data);
    log->data = NULL;
    log->n = log->cap = log->capacity = 0;
    log->dropped = 0;
}

/* -- states as bytes ------------------------------------------------------------------ */
static const unsigned char MAGIC[8] = {'D', 'F', 'W', 'B', 'S', 'T', 'A', 'T'};

void dfwb_put_u64(unsigned char *p, uint64_t u)
{
    int i;
    for (i = 0; i < 8; i++)
        p[i] = (unsigned char)(u >> (8 * i));
}

uint64_t dfwb_get_u64(const unsigned char *p)
{
    uint64_t u = 0;
    int i;
    for (i = 7; i >= 0; i--)
        u = (u << 8) | p[i];
    return u;
}

void dfwb_put_u32(unsigned char *p, uint32_t u)
{
    int i;
    for (i = 0; i < 4; i++)
        p[i] = (unsigned char)(u >> (8 * i));
}

uint32_t dfwb_get_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* zlib's CRC-32 (reflected 0xEDB88320), bit by bit: a state is a few hundred bytes */
uint32_t dfwb_crc32(const unsigned char *p, size_t n)
{
    uint32_t crc = 0xFFFFFFFFu;
    size_t i;
    int k;
    for (i = 0; i < n; i++) {
        crc ^= p[i];
        for (k = 0; k < 8; k++)
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return crc ^ 0xFFFFFFFFu;
}

void dfwb_io_writer(dfwb_io *io, unsigned char *out)
{
    io->reading = 0;
    io->out = out;
    io->in = NULL;
    io->len = 0;
    io->pos = 0;
    io->bad_int = 0;
}

void dfwb_io_reader(dfwb_io *io, const unsigned char *in, size_t len)
{
    io->reading = 1;
    io->out = NULL;
    io->in = in;
    io->len = len;
    io->pos = 0;
    io->bad_int = 0;
}

static void io_u64(dfwb_io *io, uint64_t *u)
{
    if (io->reading) {
        if (io->len - io->pos < 8 || io->pos > io->len) { /* never: the length is checked first */
            *u = 0;
            io->bad_int = 1;
            return;
        }
        *u = dfwb_get_u64(io->in + io->pos);
    } else if (io->out != NULL) {
        dfwb_put_u64(io->out + io->pos, *u);
    }
    io->pos += 8;
}

void dfwb_io_f64(dfwb_io *io, double *x)
{
    uint64_t u;
    if (!io->reading)
        memcpy(&u, x, 8);
    io_u64(io, &u);
    if (io->reading)
        memcpy(x, &u, 8);
}

void dfwb_io_i64(dfwb_io *io, long long *x)
{
    uint64_t u = 0;
    if (!io->reading)
        u = (uint64_t)*x; /* two's complement */
    io_u64(io, &u);
    if (io->reading)
        *x = u <= (uint64_t)LLONG_MAX ? (long long)u : -(long long)(~u) - 1;
}

void dfwb_io_int(dfwb_io *io, int *x)
{
    long long v = *x;
    dfwb_io_i64(io, &v);
    if (io->reading) {
        if (v < INT_MIN || v > INT_MAX) {
            io->bad_int = 1;
            v = 0;
        }
        *x = (int)v;
    }
}

void dfwb_io_motion(dfwb_io *io, dfwb_motion *m)
{
    dfwb_io_f64(io, &m->t0);
    dfwb_io_f64(io, &m->x0);
    dfwb_io_f64(io, &m->v0);
    dfwb_io_f64(io, &m->lam);
    dfwb_io_f64(io, &m->a);
    dfwb_io_f64(io, &m->b);
}

void dfwb_state_header(unsigned char *buf, int kind, size_t payload)
{
    memcpy(buf, MAGIC, 8);
    dfwb_put_u32(buf + 8, (uint32_t)DFWB_CORE_ABI);
    dfwb_put_u32(buf + 12, (uint32_t)kind);
    dfwb_put_u32(buf + 16, (uint32_t)payload);
    dfwb_put_u32(buf + 20, dfwb_crc32(buf + DFWB_STATE_HEADER, payload));
}

int dfwb_state_open(const unsigned char *buf, size_t len, int kind, size_t payload, dfwb_err *err)
{
    const char *name = dfwb_plant_name(kind);
    uint32_t abi, their_kind, declared;
    if (buf == NULL)
        return dfwb_fail(err, DFWB_E_ARGUMENT, "%s_from_bytes: NULL bytes", name);
    if (len < DFWB_STATE_HEADER)
        return dfwb_fail(err, DFWB_E_STATE, "a state of %lu bytes is truncated: its header alone has %d",
                         (unsigned long)len, DFWB_STATE_HEADER);
    if (memcmp(buf, MAGIC, 8) != 0)
        return dfwb_fail(err, DFWB_E_STATE, "these bytes are not a state of the dfwb C core (no DFWBSTAT header)");
    abi = dfwb_get_u32(buf + 8);
    if (abi != (uint32_t)DFWB_CORE_ABI)
        return dfwb_fail(err, DFWB_E_STATE, "the state was written by core ABI %lu, this core is ABI %d",
                         (unsigned long)abi, DFWB_CORE_ABI);
    their_kind = dfwb_get_u32(buf + 12);
    if (their_kind != (uint32_t)kind)
        return dfwb_fail(err, DFWB_E_STATE, "the state is one of a %s, not of a %s",
                         their_kind <= (uint32_t)INT_MAX ? dfwb_plant_name((int)their_kind) : "unknown plant", name);
    declared = dfwb_get_u32(buf + 16);
    if (declared != (uint32_t)payload || len != DFWB_STATE_HEADER + payload)
        return dfwb_fail(err, DFWB_E_STATE, "a %s state has %lu bytes, these are %lu (declaring %lu): "
                         "truncated or oversized", name, (unsigned long)(DFWB_STATE_HEADER + payload),
                         (unsigned long)len, (unsigned long)declared + DFWB_STATE_HEADER);
    if (dfwb_get_u32(buf + 20) != dfwb_crc32(buf + DFWB_STATE_HEADER, payload))
        return dfwb_fail(err, DFWB_E_STATE, "the state's checksum does not match its bytes: they are damaged");
    return DFWB_OK;
}

int dfwb_state_buffer(size_t needed, size_t buflen, dfwb_err *err)
{
    if (buflen < needed)
        return dfwb_fail(err, DFWB_E_ARGUMENT, "a buffer of %lu bytes cannot hold the state's %lu",
                         (unsigned long)buflen, (unsigned long)needed);
    return DFWB_OK;
}

int dfwb_state_check(dfwb_err *err, const char *name, double value, int ok, const char *allowed)
{
    char r[DFWB_REPR_SIZE];
    if (ok)
        return DFWB_OK;
    dfwb_repr(value, r);
    return dfwb_fail(err, DFWB_E_STATE, "the state's %s = %s is out of range: %s", name, r, allowed);
}

int dfwb_state_check_int(dfwb_err *err, const char *name, long long value, int ok, const char *allowed)
{
    if (ok)
        return DFWB_OK;
    return dfwb_fail(err, DFWB_E_STATE, "the state's %s = %lld is out of range: %s", name, value, allowed);
}

int dfwb_state_check_common(const dfwb_drive *d, int harmonics, double t, long long events, dfwb_err *err)
{
    int rc;
    if ((rc = dfwb_state_check(err, "f", d->f, isfinite(d->f), "must be finite")) != DFWB_OK
        || (rc = dfwb_state_check(err, "F", d->F, isfinite(d->F) && d->F >= 0.0, "must be finite and >= 0"))
               != DFWB_OK
        || (rc = dfwb_state_check(err, "omega", d->omega, isfinite(d->omega) && d->omega > 0.0,
                                  "must be finite and > 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "phi", d->phi, fabs(d->phi) <= DFWB_PHASE_LIMIT,
                                  "must be within +-" DFWB_PHASE_LIMIT_TEXT)) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "harmonics", harmonics, 0 <= harmonics && harmonics <= DFWB_HARMONICS_MAX,
                                      "must be in 0..10")) != DFWB_OK
        || (rc = dfwb_state_check(err, "t", t, isfinite(t) && t >= 0.0
                                  && fabs(d->omega * t + d->phi) <= DFWB_PHASE_LIMIT,
                                  "must be >= 0 with the phase omega*t + phi within +-" DFWB_PHASE_LIMIT_TEXT))
               != DFWB_OK)
        return rc;
    return dfwb_state_check_int(err, "events", events, events >= 0, "must be >= 0");
}

int dfwb_state_check_integrals(const dfwb_cx *integrals, int harmonics, dfwb_err *err)
{
    int k;
    for (k = 0; k <= DFWB_HARMONICS_MAX; k++) {
        const dfwb_cx z = integrals[k];
        const int ok = k <= harmonics ? isfinite(z.re) && isfinite(z.im) : z.re == 0.0 && z.im == 0.0;
        if (!ok)
            return dfwb_fail(err, DFWB_E_STATE, "the state's Fourier integral I_%d is out of range: %s", k,
                             k <= harmonics ? "must be finite" : "must be 0 beyond the harmonics");
    }
    return DFWB_OK;
}

int dfwb_state_motion(dfwb_motion *m, const char *name, const dfwb_drive *d, double t, dfwb_err *err)
{
    const double fields[6] = {m->t0, m->x0, m->v0, m->lam, m->a, m->b};
    static const char *const names[6] = {"t0", "x0", "v0", "lam", "a", "b"};
    char r[DFWB_REPR_SIZE];
    int i;
    for (i = 0; i < 6; i++)
        if (!isfinite(fields[i])) {
            dfwb_repr(fields[i], r);
            return dfwb_fail(err, DFWB_E_STATE, "the state's %s motion has %s = %s: must be finite", name,
                             names[i], r);
        }
    if (!(m->lam >= 0.0 && m->t0 >= 0.0 && m->t0 <= t))
        return dfwb_fail(err, DFWB_E_STATE, "the state's %s motion is out of range: needs lam >= 0 and "
                         "0 <= t0 <= t", name);
    dfwb_motion_init(m, m->t0, m->x0, m->v0, m->lam, m->a, m->b, d->omega, d->phi);
    return DFWB_OK;
}

int dfwb_state_check_piece(double t, double period, double t_piece, double searched, double analytic,
                           int has_found, double found_t, dfwb_err *err)
{
    int rc;
    if ((rc = dfwb_state_check(err, "t_piece", t_piece, isfinite(t_piece) && t_piece >= 0.0 && t_piece <= t,
                               "must be in [0, t]")) != DFWB_OK
        || (rc = dfwb_state_check(err, "searched", searched, isfinite(searched) && searched >= t_piece
                                  && searched >= t && searched <= t + period,
                                  "must be in [max(t_piece, t), t + period]")) != DFWB_OK
        || (rc = dfwb_state_check(err, "analytic", analytic, analytic >= t_piece, "must be >= t_piece (or inf)"))
               != DFWB_OK)
        return rc;
    if (has_found)
        return dfwb_state_check(err, "found", found_t, found_t >= t_piece && found_t <= searched,
                                "must be in [t_piece, searched]");
    return DFWB_OK;
}

/* -- the piece machinery ------------------------------------------------------------- */
void dfwb_pw_init(dfwb_pw *pw, double F, double omega, double phi, double f, double harmonics)
{
    int k;
    dfwb_drive_init(&pw->drive, f, F, omega, phi);
    pw->period = DFWB_TWO_PI / omega;
    pw->harmonics = (int)harmonics;
    pw->t = 0.0;
    pw->events = 0;
    for (k = 0; k <= DFWB_HARMONICS_MAX; k++)
        pw->integrals[k] = dfwb_cx_make(0.0, 0.0);
    pw->nsearch = 0;
    pw->has_found = 0;
    pw->stack.data = NULL;
    pw->stack.cap = 0;
    memset(&pw->log, 0, sizeof pw->log);
}

void dfwb_pw_set_searches(dfwb_pw *pw, double t)
{
    pw->nsearch = 0;
    pw->searched = t;
    pw->has_found = 0;
}

void dfwb_pw_begin(dfwb_pw *pw, double t, const dfwb_motion *output, double analytic, int analytic_kind)
{
    pw->t_piece = t;
    pw->output = *output;
    pw->integrated = 0;
    memset(&pw->traj, 0, sizeof pw->traj);
    pw->analytic = analytic;
    pw->analytic_kind = analytic_kind;
    dfwb_pw_set_searches(pw, t);
}

void dfwb_pw_begin_integrated(dfwb_pw *pw, double t, double x, double v, int sign, double rtol, double scale,
                              int kind)
{
    pw->t_piece = t;
    /* the motion is not the output: a body at rest at the start, its bytes canonical */
    dfwb_motion_init(&pw->output, t, x, 0.0, 0.0, 0.0, 0.0, pw->drive.omega, pw->drive.phi);
    pw->integrated = 1;
    dfwb_traj_init(&pw->traj, pw->cls->law, pw, t, x, v, sign, pw->drive.omega, pw->harmonics, rtol, scale,
                   pw->velocity_error);
    pw->analytic = INFINITY;
    pw->analytic_kind = 0;
    dfwb_pw_set_searches(pw, t);
    dfwb_pw_add_search(pw, DFWB_SEARCH_TRAJECTORY, 1.0, 0, 0.0, 0.0, 0, t, kind);
}

int dfwb_pw_state(const dfwb_pw *pw, double t, double *x, double *v, dfwb_err *err)
{
    if (pw->integrated)
        return dfwb_traj_state(&pw->traj, t, x, v, err);
    dfwb_motion_state(&pw->output, t, x, v);
    return DFWB_OK;
}

double dfwb_pw_acceleration(const dfwb_pw *pw, double t, double v)
{
    if (pw->integrated)
        return pw->cls->law(pw, pw->traj.sign, t, v);
    return dfwb_motion_acceleration(&pw->output, t, v);
}

void dfwb_pw_add_search(dfwb_pw *pw, int type, double sign, int has_level, double level, double K, int bounded,
                        double t_from, int kind)
{
    dfwb_search *s;
    if (pw->nsearch >= DFWB_MAX_SEARCHES) /* never: a piece has at most three */
        return;
    s = &pw->searches[pw->nsearch++];
    s->type = type;
    s->sign = sign;
    s->has_level = has_level;
    s->level = has_level ? level : 0.0;
    s->K = bounded ? 0.0 : K;
    s->bounded = bounded;
    s->t_from = t_from;
    s->kind = kind;
}

/* The piece's Fourier integrals from its start to t: out[0] = int x, out[k] = int x exp(-i k w s). */
static void piece_integrals(const dfwb_pw *pw, double t, dfwb_cx *out, dfwb_err *err)
{
    const dfwb_motion *m = &pw->output;
    double x, v;
    int k;
    if (t <= (pw->integrated ? pw->traj.t0 : m->t0)) {
        for (k = 0; k <= pw->harmonics; k++)
            out[k] = dfwb_cx_make(0.0, 0.0);
        return;
    }
    if (pw->integrated) {
        dfwb_traj_integrals(&pw->traj, t, out, err);
        return;
    }
    dfwb_motion_state(m, t, &x, &v);
    out[0] = dfwb_cx_real(dfwb_motion_integral(m, t, err));
    dfwb_motion_fourier(m, t, pw->harmonics, x, v, out + 1);
}

void dfwb_pw_close_piece(dfwb_pw *pw, double t, dfwb_err *err)
{
    dfwb_cx piece[DFWB_HARMONICS_MAX + 1];
    int k;
    piece_integrals(pw, t, piece, err);
    for (k = 0; k <= pw->harmonics; k++)
        pw->integrals[k] = dfwb_cx_add(pw->integrals[k], piece[k]);
    /* the errors (a closed form adds none): as PiecewisePlant._close_piece */
    pw->integral_error += (pw->integrated ? dfwb_traj_integral_error(&pw->traj, t) : 0.0)
                          + pw->position_error * (t - pw->t_piece);
    pw->position_error += pw->integrated ? dfwb_traj_position_error(&pw->traj) : 0.0;
    pw->velocity_error = pw->integrated ? dfwb_traj_velocity_error(&pw->traj, t) : 0.0;
}

double dfwb_pw_integrals_error(const dfwb_pw *pw)
{
    return pw->integral_error + (pw->integrated ? dfwb_traj_integral_error(&pw->traj, pw->t) : 0.0)
           + pw->position_error * (pw->t - pw->t_piece);
}

void dfwb_pw_integrals(const dfwb_pw *pw, double *re, double *im, dfwb_err *err)
{
    dfwb_cx piece[DFWB_HARMONICS_MAX + 1];
    int k;
    piece_integrals(pw, pw->t, piece, err);
    for (k = 0; k <= pw->harmonics; k++) {
        const dfwb_cx z = dfwb_cx_add(pw->integrals[k], piece[k]);
        re[k] = z.re;
        im[k] = z.im;
    }
}

typedef struct {
    const dfwb_pw *pw; /* the plant, seen through its first member */
    const dfwb_motion *m;
    const dfwb_search *s;
} search_ctx;

static void search_fun(const void *ctx, double t, double *g, double *dg)
{
    const search_ctx *c = (const search_ctx *)ctx;
    const dfwb_search *s = c->s;
    double x, v;
    if (s->type >= DFWB_SEARCH_PLANT) {
        c->pw->cls->search(c->pw, s, t, g, dg);
        return;
    }
    switch (s->type) {
    case DFWB_SEARCH_VELOCITY: /* VelocitySearch: (offset +) sign v, sign v' */
        v = dfwb_motion_velocity(c->m, t);
        *g = s->has_level ? s->level + s->sign * v : s->sign * v;
        *dg = s->sign * dfwb_motion_acceleration(c->m, t, v);
        return;
    case DFWB_SEARCH_POSITION: /* PositionSearch: x, v or wall - x, -v */
        dfwb_motion_state(c->m, t, &x, &v);
        if (s->has_level) {
            *g = s->level - x;
            *dg = -v;
        } else {
            *g = x;
            *dg = v;
        }
        return;
    default: /* EdgeSearch: s (edge - x), -s v */
        dfwb_motion_state(c->m, t, &x, &v);
        *g = s->sign * (s->level - x);
        *dg = -s->sign * v;
    }
}

/* CurvatureBound(subject): |v''| on [t, inf), the bound of a VELOCITY search that is bounded; the plant's own
 * bound of a search of its own type */
static double search_bound(const void *ctx, double t, dfwb_err *err)
{
    const search_ctx *c = (const search_ctx *)ctx;
    if (c->s->type >= DFWB_SEARCH_PLANT)
        return c->pw->cls->search_bound(c->pw, c->s, t);
    return dfwb_motion_curvature_bound(c->m, 1, t, err);
}

/* End of the search chunk containing t: a grid of period/8 anchored at the piece start. */
static int chunk_end(const dfwb_pw *pw, double t, double *end, dfwb_err *err)
{
    const double width = pw->period / 8.0;
    const double n = floor((t - pw->t_piece) / width) + 1.0;
    char rt[DFWB_REPR_SIZE], rw[DFWB_REPR_SIZE];
    *end = pw->t_piece + n * width;
    if (!(*end > t)) {
        *end = t + width;
        if (!(*end > t)) { /* the search would not advance */
            dfwb_repr(t, rt);
            dfwb_repr(width, rw);
            return dfwb_fail(err, DFWB_E_LIMIT,
                             "t = %s is out of range: a search chunk of %s s does not advance past it", rt, rw);
        }
    }
    return DFWB_OK;
}

/* A search's zero at root: the piece's found event if it is the earliest so far. */
static void keep_earliest(dfwb_pw *pw, double root, int kind)
{
    if (!pw->has_found || root < pw->found_t) {
        pw->has_found = 1;
        pw->found_t = root;
        pw->found_kind = kind;
    }
}

/* The piece's next event if it is <= t_end (*has = 1), searching chunk by chunk up to it. */
static int next_event(dfwb_pw *pw, const dfwb_motion *subject, double t_end, int *has, double *t_event, int *kind,
                      dfwb_err *err)
{
    double event_t;
    int event_kind, rc, i;
    while (!pw->has_found && pw->searched < (t_end < pw->analytic ? t_end : pw->analytic)) {
        const double a = pw->searched;
        double b;
        int integrated = 0;
        rc = chunk_end(pw, a, &b, err);
        if (rc != DFWB_OK)
            return rc;
        if (pw->analytic < b)
            b = pw->analytic;
        for (i = 0; i < pw->nsearch; i++) {
            const dfwb_search *s = &pw->searches[i];
            const double lo = s->t_from > a ? s->t_from : a;
            /* past an event already found the piece has ended: its functions need not be resolved there */
            double hi = pw->has_found ? pw->found_t : b;
            if (s->type == DFWB_SEARCH_TRAJECTORY) { /* it keeps one step: no further than asked */
                int found;
                double root;
                hi = t_end < hi ? t_end : hi;
                integrated = 1;
                if (lo < hi) {
                    rc = dfwb_traj_first_zero(&pw->traj, pw->cls->law, pw->cls->law_size, pw, lo, hi, &found, &root,
                                              err);
                    if (rc != DFWB_OK)
                        return rc;
                    if (found)
                        keep_earliest(pw, root, s->kind);
                }
                continue;
            }
            if (lo < hi) {
                search_ctx ctx;
                int found;
                double root;
                ctx.pw = pw;
                ctx.m = subject;
                ctx.s = s;
                rc = dfwb_first_root(search_fun, s->bounded ? search_bound : NULL, &ctx, lo, hi, s->K, &pw->stack,
                                     &found, &root, err);
                if (rc != DFWB_OK)
                    return rc;
                if (found)
                    keep_earliest(pw, root, s->kind);
            }
        }
        pw->searched = integrated && t_end < b ? t_end : b; /* an integrated search was asked to t_end at most */
    }
    if (!pw->has_found || pw->analytic <= pw->found_t) {
        event_t = pw->analytic;
        event_kind = pw->analytic_kind;
    } else {
        event_t = pw->found_t;
        event_kind = pw->found_kind;
    }
    *has = event_t <= t_end;
    *t_event = event_t;
    *kind = event_kind;
    return DFWB_OK;
}

int dfwb_pw_advance(dfwb_pw *pw, double t_end, const dfwb_motion *subject, dfwb_fire_fn fire, void *plant,
                    dfwb_err *err)
{
    double theta, span, limit, fired = 0.0, last = 0.0;
    int stalled = 0, have_last = 0;
    int rc = dfwb_check_t_end(err, pw->t, t_end);
    if (rc != DFWB_OK)
        return rc;
    rc = dfwb_drive_phase(&pw->drive, t_end, "t_end", &theta, err); /* bounds the chunks and every phase */
    if (rc != DFWB_OK)
        return rc;
    span = (t_end - pw->t) / pw->period;
    if (!(span <= DFWB_MAX_PERIODS_PER_STEP)) {
        char rp[DFWB_REPR_SIZE], rs[DFWB_REPR_SIZE], rt[DFWB_REPR_SIZE], allowed[256];
        dfwb_repr(pw->period, rp);
        dfwb_repr(span, rs);
        dfwb_repr(pw->t, rt);
        snprintf(allowed, sizeof allowed, "a step spans at most " DFWB_MAX_PERIODS_PER_STEP_TEXT " periods of the "
                 "drive (2 pi/omega = %s s), this one %s from t = %s: take smaller steps", rp, rs, rt);
        return dfwb_check(err, "t_end", t_end, 0, allowed);
    }
    limit = DFWB_EVENTS_PER_PERIOD_LIMIT * (1.0 + span);
    for (;;) {
        int has, kind, counted = 0;
        double t_event;
        rc = next_event(pw, subject, t_end, &has, &t_event, &kind, err);
        if (rc != DFWB_OK || !has || err->overflow != NULL)
            break;
        fired += 1.0;
        stalled = have_last && t_event - last <= DFWB_STALL_ULPS * DFWB_EPS * fabs(t_event) ? stalled + 1 : 0;
        last = t_event;
        have_last = 1;
        if (stalled > DFWB_STALL_EVENTS) {
            char rte[DFWB_REPR_SIZE];
            dfwb_repr(t_event, rte);
            rc = dfwb_fail(err, DFWB_E_LIMIT, "more than %d events within %d ulp of each other at t = %s (last "
                           "event: %s): the motion chatters below the resolution of time", DFWB_STALL_EVENTS,
                           DFWB_STALL_ULPS, rte, dfwb_event_name(kind));
            break;
        }
        if (fired > limit) {
            char rt[DFWB_REPR_SIZE], rte[DFWB_REPR_SIZE];
            dfwb_repr(pw->t, rt);
            dfwb_repr(t_event, rte);
            rc = dfwb_fail(err, DFWB_E_LIMIT,
                           "more than %d events per period between t = %s and t = %s (last event: %s); the "
                           "motion chatters below the plant's resolution",
                           DFWB_EVENTS_PER_PERIOD_LIMIT, rt, rte, dfwb_event_name(kind));
            break;
        }
        if (fired > DFWB_MAX_EVENTS_PER_STEP) {
            char rt[DFWB_REPR_SIZE], rte[DFWB_REPR_SIZE];
            dfwb_repr(pw->t, rt);
            dfwb_repr(t_event, rte);
            rc = dfwb_fail(err, DFWB_E_LIMIT, "more than %d events in one step between t = %s and t = %s (last "
                           "event: %s): take smaller steps", DFWB_MAX_EVENTS_PER_STEP, rt, rte, dfwb_event_name(kind));
            break;
        }
        rc = fire(plant, t_event, kind, &counted, err);
        if (rc != DFWB_OK || err->overflow != NULL) /* Python raised there: not counted */
            break;
        if (counted) {
            pw->events += 1;
            dfwb_log_add(&pw->log, t_event, kind);
        }
    }
    if (rc == DFWB_OK && err->overflow == NULL)
        pw->t = t_end;
    return rc;
}

int dfwb_pw_set_input(dfwb_pw *pw, double f, dfwb_restart_fn restart, void *plant, dfwb_err *err)
{
    int rc = dfwb_check(err, "f", f, 1, "the input f must be a finite number (N)");
    if (rc != DFWB_OK)
        return rc;
    if (f != pw->drive.f) {
        dfwb_pw_close_piece(pw, pw->t, err);
        dfwb_drive_init(&pw->drive, f, pw->drive.F, pw->drive.omega, pw->drive.phi);
        rc = restart(plant, pw->t, err);
    }
    return rc;
}

int dfwb_pw_same_parameters(const dfwb_pw *a, const dfwb_pw *b)
{
    return dfwb_same_double(a->drive.F, b->drive.F) && dfwb_same_double(a->drive.omega, b->drive.omega)
           && dfwb_same_double(a->drive.phi, b->drive.phi) && dfwb_same_double(a->period, b->period)
           && a->harmonics == b->harmonics;
}

/* -- the common part of a state ----------------------------------------------------------- */
/* The trajectory's fields (zeros when the piece is not integrated: dfwb_pw_begin clears it). */
static void traj_io(dfwb_io *io, dfwb_trajectory *tr)
{
    int k;
    dfwb_io_int(io, &tr->sign);
    dfwb_io_int(io, &tr->harmonics);
    dfwb_io_f64(io, &tr->t0);
    dfwb_io_f64(io, &tr->x0);
    dfwb_io_f64(io, &tr->v0);
    dfwb_io_f64(io, &tr->omega);
    dfwb_io_f64(io, &tr->rtol);
    dfwb_io_f64(io, &tr->scale);
    dfwb_io_f64(io, &tr->max_step);
    dfwb_io_f64(io, &tr->h);
    dfwb_io_f64(io, &tr->k_last);
    dfwb_io_f64(io, &tr->peak[0]);
    dfwb_io_f64(io, &tr->peak[1]);
    dfwb_io_f64(io, &tr->error[0]);
    dfwb_io_f64(io, &tr->error[1]);
    dfwb_io_int(io, &tr->has_stopped);
    dfwb_io_f64(io, &tr->stopped);
    dfwb_io_i64(io, &tr->taken);
    dfwb_io_int(io, &tr->stiff[0]);
    dfwb_io_int(io, &tr->stiff[1]);
    dfwb_io_f64(io, &tr->a);
    dfwb_io_f64(io, &tr->sh);
    dfwb_io_f64(io, &tr->d0);
    dfwb_io_f64(io, &tr->sv0);
    for (k = 0; k < 5; k++)
        dfwb_io_f64(io, &tr->quintic[k]);
    for (k = 0; k < 4; k++)
        dfwb_io_f64(io, &tr->vc[k]);
    for (k = 0; k <= DFWB_HARMONICS_MAX; k++) {
        dfwb_io_f64(io, &tr->integrals[k].re);
        dfwb_io_f64(io, &tr->integrals[k].im);
    }
    dfwb_io_f64(io, &tr->int_err);
    dfwb_io_f64(io, &tr->pos_err);
}

/* A trajectory read from a state: every field in range and consistent with its piece (DFWB_E_STATE). */
static int traj_validate(const dfwb_pw *pw, dfwb_err *err)
{
    const dfwb_trajectory *tr = &pw->traj;
    const double end = tr->a + tr->sh;
    int ok, k;
    if (!pw->integrated) {
        static const dfwb_trajectory zero = {0};
        return memcmp(tr, &zero, sizeof zero) == 0 ? DFWB_OK
               : dfwb_fail(err, DFWB_E_STATE, "the state's trajectory is out of range: must be zeros when the piece "
                           "is not integrated");
    }
    ok = (tr->sign == 1 || tr->sign == -1) && tr->harmonics == pw->harmonics && tr->t0 == pw->t_piece
         && isfinite(tr->x0) && isfinite(tr->v0) && tr->omega == pw->drive.omega && tr->rtol >= 1e-12
         && tr->rtol <= 1e-3 && tr->scale > 0.0 /* +inf allowed: no feature */ && tr->max_step == DFWB_TWO_PI / tr->omega / DFWB_IN_STEPS_PER_PERIOD
         && isfinite(tr->h) && tr->h > 0.0 && isfinite(tr->k_last) && isfinite(tr->peak[0]) && tr->peak[0] >= 0.0
         && isfinite(tr->peak[1]) && tr->peak[1] >= 0.0 && isfinite(tr->error[0]) && tr->error[0] >= 0.0
         && isfinite(tr->error[1]) && tr->error[1] >= 0.0 && tr->taken >= 0 && 0 <= tr->stiff[0]
         && tr->stiff[0] < DFWB_IN_STIFF_STEPS && 0 <= tr->stiff[1] && tr->stiff[1] < 6 && isfinite(tr->a)
         && isfinite(tr->sh) && tr->sh >= 0.0 && tr->a >= tr->t0 && tr->a <= pw->t && end >= pw->t
         && (tr->has_stopped == 0 ? tr->stopped == 0.0 : tr->has_stopped == 1 && tr->stopped >= tr->a
             && tr->stopped <= end)
         && isfinite(tr->d0) && isfinite(tr->sv0) && isfinite(tr->int_err) && tr->int_err >= 0.0
         && isfinite(tr->pos_err) && tr->pos_err >= 0.0;
    for (k = 0; ok && k < 5; k++)
        ok = isfinite(tr->quintic[k]);
    for (k = 0; ok && k < 4; k++)
        ok = isfinite(tr->vc[k]);
    for (k = 0; ok && k <= DFWB_HARMONICS_MAX; k++)
        ok = isfinite(tr->integrals[k].re) && isfinite(tr->integrals[k].im)
             && (k <= tr->harmonics || (tr->integrals[k].re == 0.0 && tr->integrals[k].im == 0.0));
    if (!ok)
        return dfwb_fail(err, DFWB_E_STATE, "the state's trajectory is out of range: needs a direction +-1, the "
                         "piece's start, the drive's omega, rtol in [1e-12, 1e-3], finite steps, errors >= 0 and "
                         "a last step that holds the current time");
    dfwb_in_setup();
    return DFWB_OK;
}

void dfwb_pw_io(dfwb_io *io, dfwb_pw *pw)
{
    /* writing: canonical bytes, nothing stale (unused searches and a missing found are zeros) */
    const int blank_found = !io->reading && !pw->has_found;
    double found_t = blank_found ? 0.0 : pw->found_t;
    int found_kind = blank_found ? 0 : pw->found_kind;
    int k, i;
    dfwb_io_f64(io, &pw->drive.f);
    dfwb_io_f64(io, &pw->drive.F);
    dfwb_io_f64(io, &pw->drive.omega);
    dfwb_io_f64(io, &pw->drive.phi);
    dfwb_io_int(io, &pw->harmonics);
    dfwb_io_f64(io, &pw->t);
    dfwb_io_i64(io, &pw->events);
    for (k = 0; k <= DFWB_HARMONICS_MAX; k++) {
        dfwb_io_f64(io, &pw->integrals[k].re);
        dfwb_io_f64(io, &pw->integrals[k].im);
    }
    dfwb_io_f64(io, &pw->integral_error);
    dfwb_io_f64(io, &pw->position_error);
    dfwb_io_f64(io, &pw->velocity_error);
    dfwb_io_f64(io, &pw->t_piece);
    dfwb_io_motion(io, &pw->output);
    dfwb_io_int(io, &pw->integrated);
    traj_io(io, &pw->traj);
    dfwb_io_f64(io, &pw->analytic);
    dfwb_io_int(io, &pw->analytic_kind);
    dfwb_io_int(io, &pw->nsearch);
    for (i = 0; i < DFWB_MAX_SEARCHES; i++) {
        dfwb_search blank, *s = &pw->searches[i];
        if (!io->reading && i >= pw->nsearch) {
            memset(&blank, 0, sizeof blank);
            s = &blank;
        }
        dfwb_io_int(io, &s->type);
        dfwb_io_f64(io, &s->sign);
        dfwb_io_int(io, &s->has_level);
        dfwb_io_f64(io, &s->level);
        dfwb_io_f64(io, &s->K);
        dfwb_io_int(io, &s->bounded);
        dfwb_io_f64(io, &s->t_from);
        dfwb_io_int(io, &s->kind);
    }
    dfwb_io_f64(io, &pw->searched);
    dfwb_io_int(io, &pw->has_found);
    dfwb_io_f64(io, &found_t);
    dfwb_io_int(io, &found_kind);
    if (io->reading) {
        pw->found_t = found_t;
        pw->found_kind = found_kind;
    }
}

int dfwb_pw_validate(dfwb_pw *pw, dfwb_err *err)
{
    int rc, i;
    pw->stack.data = NULL;
    pw->stack.cap = 0;
    memset(&pw->log, 0, sizeof pw->log);
    rc = dfwb_state_check_common(&pw->drive, pw->harmonics, pw->t, pw->events, err);
    if (rc != DFWB_OK)
        return rc;
    pw->period = DFWB_TWO_PI / pw->drive.omega;
    if ((rc = dfwb_state_check_integrals(pw->integrals, pw->harmonics, err)) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "has_found", pw->has_found, pw->has_found == 0 || pw->has_found == 1,
                                      "must be 0 or 1")) != DFWB_OK
        || (rc = dfwb_state_check_piece(pw->t, pw->period, pw->t_piece, pw->searched, pw->analytic, pw->has_found,
                                        pw->found_t, err)) != DFWB_OK
        || (rc = dfwb_state_motion(&pw->output, "output", &pw->drive, pw->t, err)) != DFWB_OK
        || (rc = dfwb_state_check(err, "output motion's t0", pw->output.t0, pw->output.t0 == pw->t_piece,
                                  "must be the piece's start t_piece")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "nsearch", pw->nsearch, 0 <= pw->nsearch
                                      && pw->nsearch <= DFWB_MAX_SEARCHES, "must be in 0..3")) != DFWB_OK
        || (rc = dfwb_state_check(err, "integral_error", pw->integral_error, isfinite(pw->integral_error)
                                  && pw->integral_error >= 0.0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "position_error", pw->position_error, isfinite(pw->position_error)
                                  && pw->position_error >= 0.0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check(err, "velocity_error", pw->velocity_error, isfinite(pw->velocity_error)
                                  && pw->velocity_error >= 0.0, "must be >= 0")) != DFWB_OK
        || (rc = dfwb_state_check_int(err, "integrated", pw->integrated, pw->integrated == 0
                                      || (pw->integrated == 1 && pw->cls->law != NULL),
                                      "must be 0, or 1 for a plant with integrated pieces")) != DFWB_OK
        || (rc = traj_validate(pw, err)) != DFWB_OK)
        return rc;
    if (!isinf(pw->analytic) && pw->analytic_kind == 0)
        return dfwb_fail(err, DFWB_E_STATE, "the state's analytic event is out of range: a finite one has a kind");
    if (!pw->has_found && !(pw->found_t == 0.0 && pw->found_kind == 0))
        return dfwb_fail(err, DFWB_E_STATE, "the state's found event is out of range: must be 0 when none is found");
    for (i = 0; i < DFWB_MAX_SEARCHES; i++) {
        const dfwb_search *s = &pw->searches[i];
        if (i >= pw->nsearch) {
            if (s->type != 0 || s->sign != 0.0 || s->has_level != 0 || s->level != 0.0 || s->K != 0.0
                || s->bounded != 0 || s->t_from != 0.0 || s->kind != 0)
                return dfwb_fail(err, DFWB_E_STATE, "the state's search %d is out of range: an unused search "
                                 "must be zeros", i);
            continue;
        }
        if ((s->type == DFWB_SEARCH_TRAJECTORY) != (pw->integrated && i == 0))
            return dfwb_fail(err, DFWB_E_STATE, "the state's search %d is out of range: an integrated piece's one "
                             "search is its trajectory's stop, and only its", i);
        if (!((s->type == DFWB_SEARCH_VELOCITY || s->type == DFWB_SEARCH_POSITION || s->type == DFWB_SEARCH_EDGE
               || s->type == DFWB_SEARCH_TRAJECTORY || (s->type >= DFWB_SEARCH_PLANT && pw->cls->search != NULL))
              && (s->sign == 1.0 || s->sign == -1.0) && (s->has_level == 0 || s->has_level == 1)
              && isfinite(s->level) && (s->has_level || s->level == 0.0) && s->K >= 0.0 /* +inf allowed */
              && (s->bounded == 0
                  || (s->bounded == 1 && s->K == 0.0
                      && (s->type == DFWB_SEARCH_VELOCITY
                          || (s->type >= DFWB_SEARCH_PLANT && pw->cls->search_bound != NULL))))
              && s->t_from >= pw->t_piece /* +inf allowed: it never starts */))
            return dfwb_fail(err, DFWB_E_STATE, "the state's search %d is out of range: needs a known type, "
                             "sign +-1, a finite level, K >= 0 (0 when bounded: a velocity search's or the plant's "
                             "own) and t_from >= t_piece", i);
    }
    if (pw->has_found) {
        for (i = 0; i < pw->nsearch; i++)
            if (pw->searches[i].kind == pw->found_kind)
                return DFWB_OK;
        return dfwb_fail(err, DFWB_E_STATE, "the state's found event is out of range: its kind is none of "
                         "the pending searches'");
    }
    return DFWB_OK;
}

/* -- what every plant's API does alike ----------------------------------------------------------- */
int dfwb_core_abi_version(void) { return DFWB_CORE_ABI; }

const dfwb_plant_class *dfwb_plant_class_of(int kind)
{
#define DFWB_CLASS_CASE(kind, name)                                                                                \
    case kind: return &dfwb_##name##_class;
    switch (kind) {
        DFWB_PLANTS(DFWB_CLASS_CASE)
    default: return NULL;
    }
#undef DFWB_CLASS_CASE
}

int dfwb_plant_shape(int kind, size_t *nparams, size_t *noutputs, size_t *ncounters)
{
    const dfwb_plant_class *cls = dfwb_plant_class_of(kind);
    if (cls == NULL)
        return DFWB_E_ARGUMENT;
    if (nparams != NULL)
        *nparams = cls->nparams;
    if (noutputs != NULL)
        *noutputs = cls->noutputs;
    if (ncounters != NULL)
        *ncounters = cls->ncounters;
    return DFWB_OK;
}

/* A zeroed instance of cls (DFWB_E_MEMORY, *out NULL, when out of memory). */
static int plant_alloc(const dfwb_plant_class *cls, dfwb_plant **out, dfwb_err *err)
{
    *out = calloc(1, cls->size);
    if (*out == NULL)
        return dfwb_fail(err, DFWB_E_MEMORY, "out of memory (a %s)", dfwb_plant_name(cls->kind));
    (*out)->pw.cls = cls;
    return DFWB_OK;
}

/* The end of making a plant: rc OK gives *out = p, else p is freed (*out NULL). */
static int plant_created(dfwb_plant *p, int rc, dfwb_plant **out)
{
    if (rc != DFWB_OK) {
        dfwb_plant_free(p);
        *out = NULL;
        return rc;
    }
    *out = p;
    return DFWB_OK;
}

int dfwb_plant_new(int kind, const double *params, size_t nparams, dfwb_plant **out, char *errbuf, size_t errlen)
{
    const dfwb_plant_class *cls = dfwb_plant_class_of(kind);
    dfwb_plant *p;
    dfwb_err err;
    int rc;
    dfwb_err_init(&err, errbuf, errlen);
    if (out == NULL || params == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_plant_new: NULL params or out");
    *out = NULL;
    if (cls == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_plant_new: unknown plant kind %d", kind);
    if (nparams != cls->nparams)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_plant_new: a %s takes %lu parameters, not %lu",
                         dfwb_plant_name(kind), (unsigned long)cls->nparams, (unsigned long)nparams);
    if ((rc = plant_alloc(cls, &p, &err)) != DFWB_OK)
        return rc;
    return plant_created(p, cls->init(p, params, &err), out);
}

int dfwb_plant_kind(const dfwb_plant *p) { return p == NULL ? 0 : p->pw.cls->kind; }

static const dfwb_motion *subject_of(const dfwb_pw *pw)
{
    return (const dfwb_motion *)(const void *)((const char *)pw + pw->cls->subject);
}

int dfwb_plant_set_input(dfwb_plant *p, double f, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_err_init(&err, errbuf, errlen);
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_plant_set_input: NULL instance");
    return dfwb_err_finish(&err, dfwb_pw_set_input(&p->pw, f, p->pw.cls->restart, p, &err));
}

int dfwb_plant_advance(dfwb_plant *p, double t_end, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_err_init(&err, errbuf, errlen);
    if (p == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_plant_advance: NULL instance");
    return dfwb_err_finish(&err, dfwb_pw_advance(&p->pw, t_end, subject_of(&p->pw), p->pw.cls->fire, p, &err));
}

void dfwb_plant_output(const dfwb_plant *p, double *out)
{
    if (p != NULL && out != NULL)
        p->pw.cls->output(p, out);
}

int dfwb_plant_integrals(const dfwb_plant *p, double *re, double *im, char *errbuf, size_t errlen)
{
    dfwb_err err;
    dfwb_err_init(&err, errbuf, errlen);
    if (p == NULL || re == NULL || im == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_plant_integrals: NULL instance or array");
    dfwb_pw_integrals(&p->pw, re, im, &err);
    return dfwb_err_finish(&err, DFWB_OK);
}

double dfwb_plant_integrals_error(const dfwb_plant *p) { return p == NULL ? NAN : dfwb_pw_integrals_error(&p->pw); }

double dfwb_plant_time(const dfwb_plant *p) { return p == NULL ? NAN : p->pw.t; }

long long dfwb_plant_events(const dfwb_plant *p) { return p == NULL ? -1 : p->pw.events; }

int dfwb_plant_harmonics(const dfwb_plant *p) { return p == NULL ? -1 : p->pw.harmonics; }

double dfwb_plant_period(const dfwb_plant *p) { return p == NULL ? NAN : p->pw.period; }

void dfwb_plant_drive(const dfwb_plant *p, double out[4])
{
    if (p != NULL && out != NULL)
        dfwb_drive_values(&p->pw.drive, out);
}

long long dfwb_plant_counter(const dfwb_plant *p, size_t i)
{
    return p == NULL || i >= p->pw.cls->ncounters ? -1 : p->pw.cls->counter(p, i);
}

int dfwb_plant_same_parameters(const dfwb_plant *a, const dfwb_plant *b)
{
    if (a == NULL || b == NULL || a->pw.cls != b->pw.cls)
        return 0;
    return dfwb_pw_same_parameters(&a->pw, &b->pw) && a->pw.cls->same(a, b);
}

dfwb_plant *dfwb_plant_copy(const dfwb_plant *p)
{
    dfwb_plant *copy;
    if (p == NULL)
        return NULL;
    copy = (dfwb_plant *)malloc(p->pw.cls->size);
    if (copy == NULL)
        return NULL;
    memcpy(copy, p, p->pw.cls->size); /* the whole plant: pw is its first member */
    copy->pw.stack.data = NULL;        /* a workspace of its own */
    copy->pw.stack.cap = 0;
    if (!dfwb_log_copy(&copy->pw.log, &p->pw.log)) {
        free(copy);
        return NULL;
    }
    return copy;
}

void dfwb_plant_free(dfwb_plant *p)
{
    if (p == NULL)
        return;
    dfwb_stack_free(&p->pw.stack);
    dfwb_log_free(&p->pw.log);
    free(p);
}

void dfwb_plant_log(dfwb_plant *p, size_t capacity)
{
    if (p != NULL)
        dfwb_log_enable(&p->pw.log, capacity);
}

size_t dfwb_plant_log_read(dfwb_plant *p, double *t, int *kind, size_t max)
{
    return p == NULL ? 0 : dfwb_log_read(&p->pw.log, t, kind, max);
}

unsigned long long dfwb_plant_log_dropped(const dfwb_plant *p) { return p == NULL ? 0 : p->pw.log.dropped; }

/* The payload's bytes: the plant's fields counted on its zeroed instance (writing nothing, changing nothing). */
static size_t payload_size(const dfwb_plant_class *cls)
{
    dfwb_io io;
    dfwb_io_writer(&io, NULL);
    cls->io(&io, (void *)cls->zero);
    return io.pos;
}

size_t dfwb_plant_state_size(int kind)
{
    const dfwb_plant_class *cls = dfwb_plant_class_of(kind);
    return cls == NULL ? 0 : DFWB_STATE_HEADER + payload_size(cls);
}

int dfwb_plant_to_bytes(const dfwb_plant *p, unsigned char *buf, size_t buflen, size_t *size, char *errbuf,
                        size_t errlen)
{
    dfwb_err err;
    dfwb_io io;
    size_t payload;
    int rc;
    dfwb_err_init(&err, errbuf, errlen);
    if (p == NULL || size == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_plant_to_bytes: NULL instance or size");
    payload = payload_size(p->pw.cls);
    *size = DFWB_STATE_HEADER + payload;
    if (buf == NULL) /* a size query */
        return DFWB_OK;
    rc = dfwb_state_buffer(*size, buflen, &err);
    if (rc != DFWB_OK)
        return rc;
    dfwb_io_writer(&io, buf + DFWB_STATE_HEADER);
    p->pw.cls->io(&io, (void *)p); /* writing reads the plant only */
    dfwb_state_header(buf, p->pw.cls->kind, payload);
    return DFWB_OK;
}

int dfwb_plant_from_bytes(int kind, const unsigned char *buf, size_t len, dfwb_plant **out, char *errbuf,
                          size_t errlen)
{
    const dfwb_plant_class *cls = dfwb_plant_class_of(kind);
    dfwb_err err;
    dfwb_io io;
    dfwb_plant *p;
    size_t payload;
    int rc;
    dfwb_err_init(&err, errbuf, errlen);
    if (out == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_plant_from_bytes: NULL out");
    *out = NULL;
    if (cls == NULL)
        return dfwb_fail(&err, DFWB_E_ARGUMENT, "dfwb_plant_from_bytes: unknown plant kind %d", kind);
    payload = payload_size(cls);
    rc = dfwb_state_open(buf, len, cls->kind, payload, &err);
    if (rc != DFWB_OK)
        return rc;
    rc = plant_alloc(cls, &p, &err);
    if (rc != DFWB_OK)
        return rc;
    dfwb_io_reader(&io, buf + DFWB_STATE_HEADER, payload);
    cls->io(&io, p);
    if (io.bad_int)
        rc = dfwb_fail(&err, DFWB_E_STATE, "the state holds an integer field out of range");
    else if ((rc = dfwb_pw_validate(&p->pw, &err)) == DFWB_OK)
        rc = cls->validate(p, &err);
    return plant_created(p, rc, out);
}
