/* A hostile FMI 2.0 host: random sequences of FMI calls, in orders and with arguments
 * the standard forbids or leaves odd, against one of our FMUs, checking each answer.
 *
 *   fuzz_host DIR ID SEED OPS [verbose] [hostile]
 *
 * Up to three instances live at once; each op picks one (or instantiates/frees) and calls
 * one FMI function with arguments drawn from valid ones and hostile ones (NULL arrays,
 * n = 0, unknown value references, NaN/inf values, wrong phases, odd step sizes and
 * communication points, states taken by another instance or in another phase, serialised
 * and cut, extended or changed, input derivatives of order 0/3/-1, unknown status kinds,
 * Strings that are long, not UTF-8 or printf formats, or the pointers fmi2GetString gave,
 * written back). With ``hostile``, also pointers that are no state (freed ones, the
 * host's own memory, odd addresses). ``verbose`` prints each op and log line. The host
 * keeps its own model of each instance's FMI phase and time and checks:
 *
 *   - every status is one of fmi2OK .. fmi2Fatal, every log line has a category;
 *   - a call FMI 2.0 forbids in the phase (or with the arguments) is not answered fmi2OK,
 *     nor a read of an output before initialisation mode, which has no value there yet;
 *   - fmi2GetReal answered fmi2OK gives finite values, fmi2GetRealStatus a finite time;
 *   - the time after an fmi2OK step is the step's end (fmi2LastSuccessfulTime);
 *   - a state this FMU took is set with fmi2OK while the instance that took (or
 *     deserialised) it lives (fmi2FreeInstance frees the states its instance still
 *     holds), intact serialised bytes deserialise and changed ones do not.
 *
 * Each violation is printed as "VIOLATION op N: ..."; the last line is "fuzz: N ops, V
 * violations". Crashes and memory errors are left to the process (and ASan / valgrind).
 */
#include <dlfcn.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_callbacks.h"

typedef void *Component;
typedef int (*Fn0)(Component);

static struct {
    Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *,
                             int, int);
    void (*free_instance)(Component);
    int (*setup)(Component, int, double, double, int, double);
    Fn0 enter_init, exit_init, terminate, reset, cancel;
    int (*do_step)(Component, double, double, int);
    int (*get_real)(Component, const Vr *, size_t, double *);
    int (*set_real)(Component, const Vr *, size_t, const double *);
    int (*get_integer)(Component, const Vr *, size_t, int *);
    int (*set_integer)(Component, const Vr *, size_t, const int *);
    int (*get_boolean)(Component, const Vr *, size_t, int *);
    int (*set_boolean)(Component, const Vr *, size_t, const int *);
    int (*get_string)(Component, const Vr *, size_t, const char **);
    int (*set_string)(Component, const Vr *, size_t, const char *const *);
    int (*get_state)(Component, void **);
    int (*set_state)(Component, void *);
    int (*free_state)(Component, void **);
    int (*state_size)(Component, void *, size_t *);
    int (*serialize)(Component, void *, char *, size_t);
    int (*deserialize)(Component, const char *, size_t, void **);
    int (*set_derivatives)(Component, const Vr *, size_t, const int *, const double *);
    int (*get_derivatives)(Component, const Vr *, size_t, const int *, double *);
    int (*directional)(Component, const Vr *, size_t, const Vr *, size_t, const double *,
                       double *);
    int (*get_status)(Component, int, int *);
    int (*get_real_status)(Component, int, double *);
    int (*get_integer_status)(Component, int, int *);
    int (*get_boolean_status)(Component, int, int *);
    int (*get_string_status)(Component, int, const char **);
    int (*debug_logging)(Component, int, size_t, const char *const *);
} F;

/* ---- the FMU's variables (resources/fmu_variables.txt) ------------------------------- */

typedef struct {
    Vr vr;
    char type;
    char causality[24], variability[16];
    double low, high, start;
} Var;

static Var vars[512];
static size_t nvars;
static char guid[128], resources[4200];

static void read_variables(const char *dir)
{
    char path[4300], line[512], t[4], ca[24], va[16], lo[40], hi[40], st[40], name[128];
    snprintf(path, sizeof path, "%s/resources/fmu_variables.txt", dir);
    FILE *in = fopen(path, "r");
    while (in && nvars < 512 && fgets(line, sizeof line, in)) {
        Var *v = &vars[nvars];
        if (sscanf(line, "%u %3s %23s %15s %39s %39s %39s %127s", &v->vr, t, ca, va, lo, hi,
                   st, name) != 8) {
            continue;
        }
        v->type = t[0];
        snprintf(v->causality, sizeof v->causality, "%s", ca);
        snprintf(v->variability, sizeof v->variability, "%s", va);
        v->low = strcmp(lo, "-") ? strtod(lo, NULL) : -INFINITY;
        v->high = strcmp(hi, "-") ? strtod(hi, NULL) : INFINITY;
        v->start = strcmp(st, "-") ? strtod(st, NULL) : NAN;
        nvars++;
    }
    if (in) fclose(in);
}

/* ---- randomness (xorshift64*: the same sequence for a seed on every machine) -------- */

static uint64_t rng = 88172645463325252ull;
static uint64_t next(void)
{
    rng ^= rng >> 12;
    rng ^= rng << 25;
    rng ^= rng >> 27;
    return rng * 2685821657736338717ull;
}
static unsigned pick(unsigned n) { return n ? (unsigned)(next() % n) : 0; }
static int chance(unsigned percent) { return pick(100) < percent; }

static const double ODD[] = {0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300, 5e-324, 1e300, -1e300,
                             DBL_MAX, -DBL_MAX, INFINITY, -INFINITY, NAN, -NAN, 0.01, 1e9,
                             2.5, 100.0, 101.0, -101.0};
#define N_ODD (sizeof ODD / sizeof ODD[0])

/* ---- the host's model of each instance ----------------------------------------------- */

enum { NONE, INSTANTIATED, INITIALIZATION, INITIALIZED, TERMINATED, FAILED };
static const char *PHASE[] = {"none", "instantiated", "initialisation", "initialised",
                              "terminated", "failed"};

typedef struct {
    Component c;
    int phase;
    double time, stop;
} Inst;

typedef struct {
    void *state;
    int owner; /* the instance slot that took it */
    int phase;
    double time;
} SavedState;

#define INSTANCES 3
#define STATES 8
static Inst inst[INSTANCES];
static SavedState states[STATES];
static char *blob;
static size_t blob_size;
static int blob_phase;
static double blob_time;
static int verbose, violations;
static long op;
static int current; /* the instance slot of the op */
static int interpolates;
static int hostile; /* pointers that are no state (freed ones among them) */
static void *graveyard[16]; /* states freed (hostile) */
static unsigned buried;

static void logger(void *env, const char *name, int status, const char *category,
                   const char *message, ...)
{
    (void)env;
    char text[8192];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message, args);
    va_end(args);
    if (!category) {
        printf("VIOLATION op %ld: a log message without a category\n", op);
        violations++;
    }
    if (status < 0 || status > 4) {
        printf("VIOLATION op %ld: a log message of status %d\n", op, status);
        violations++;
    }
    if (verbose) printf("  log %s [%d] {%s} %.300s\n", name ? name : "(null)", status,
                        category ? category : "(null)", text);
}

static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};

static void violation(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    printf("VIOLATION op %ld: ", op);
    vprintf(format, args);
    printf("\n");
    va_end(args);
    violations++;
}

static int status_ok(int s, const char *call)
{
    if (s < 0 || s > 4) violation("%s returned status %d", call, s);
    return s;
}

/* A call the host's model says FMI 2.0 forbids must not be answered OK or Warning. */
static void forbidden(int s, const char *call, const char *why)
{
    if (s <= 1) violation("%s answered %d although %s", call, s, why);
}

#define TRACE(...)                                     \
    do {                                               \
        if (verbose) {                                 \
            printf("op %ld [%d]: ", op, current);      \
            printf(__VA_ARGS__);                       \
            printf("\n");                              \
        }                                              \
    } while (0)

/* ---- value references and values --------------------------------------------------- */

static Vr random_vr(char type)
{
    unsigned k = pick(100);
    if (k < 5) return (Vr)(nvars + pick(5));
    if (k < 7) return UINT_MAX - pick(3);
    if (k < 9) return 100001;
    if (k < 15) return vars[pick((unsigned)nvars)].vr; /* any type */
    for (int tries = 0; tries < 50; tries++) {
        const Var *v = &vars[pick((unsigned)nvars)];
        if (v->type == type) return v->vr;
    }
    return vars[0].vr;
}

static const Var *var_of(Vr vr)
{
    for (size_t i = 0; i < nvars; i++) {
        if (vars[i].vr == vr) return &vars[i];
    }
    return NULL;
}

static double random_real(const Var *v)
{
    if (chance(30)) return ODD[pick(N_ODD)];
    if (v && isfinite(v->start)) return v->start + (chance(50) ? 0.0 : (double)pick(5) - 2.0);
    return (double)pick(21) - 10.0;
}

static const char *random_string(void)
{
    static char big[70000];
    static const char *const texts[] = {"remus100", "", "%s%s%s%n%n", "\xff\xfe", "\xc0\x80",
                                        "\xed\xa0\x80", "caf\xc3\xa9", "[[0,0,0],[10,0,0]]",
                                        "[[0, 0, 5], [100, 0, 5], [100, 100, 5]]", "garbage",
                                        "\xf4\x90\x80\x80", "a\nb"};
    unsigned k = pick(14);
    if (k < 12) return texts[k];
    size_t n = k == 12 ? 5000 : sizeof big - 1;
    for (size_t i = 0; i < n; i++) big[i] = (char)('a' + i % 26);
    big[n] = '\0';
    if (chance(50)) big[n / 2] = '%';
    return big;
}

/* Whether FMI 2.0 (and the variable's declaration) allows writing ``v`` now with ``x``. */
static int writable(const Inst *in, const Var *v, char type, double x, int *maybe)
{
    *maybe = 0;
    if (!v || v->type != type) return 0;
    if (in->phase >= TERMINATED || in->phase == NONE) return 0;
    if (type == 'R' && !isfinite(x)) return 0;
    if (type != 'S' && (x < v->low || x > v->high)) return 0;
    if (!strcmp(v->causality, "input")) return 1;
    if (!strcmp(v->causality, "parameter")) {
        if (strcmp(v->variability, "fixed")) return 1;
        if (in->phase <= INITIALIZATION) return 1;
        *maybe = 1; /* the value it has: allowed */
        return 0;
    }
    return 0;
}

/* ---- the operations ---------------------------------------------------------------- */

static int slot_of_live(void)
{
    int live[INSTANCES], n = 0;
    for (int i = 0; i < INSTANCES; i++) {
        if (inst[i].c) live[n++] = i;
    }
    return n ? live[pick((unsigned)n)] : -1;
}

/* The states instance slot ``k`` took or deserialised: gone with it (its fmi2FreeInstance
 * frees them), so neither set nor freed again. */
static void forget_states_of(int k)
{
    for (int j = 0; j < STATES; j++) {
        if (states[j].state && states[j].owner == k) states[j].state = NULL;
    }
}

static void do_instantiate(int k)
{
    if (inst[k].c) {
        TRACE("free %d", k);
        F.free_instance(inst[k].c);
        memset(&inst[k], 0, sizeof inst[k]);
        forget_states_of(k);
        return;
    }
    const char *name = "fuzz", *g = guid, *r = resources;
    int type = 1;
    const Callbacks *cb = &callbacks;
    static Callbacks no_logger = {NULL, calloc, free, NULL, NULL};
    int bad = 1;
    switch (pick(10)) {
    case 0: name = NULL; break;
    case 1: g = NULL; break;
    case 2: g = "{nope}"; break;
    case 3: r = NULL; break;
    case 4: type = 0; break;
    case 5: r = "file:///nonexistent/resources"; break;
    case 6: cb = &no_logger; bad = 0; break;
    default: bad = 0;
    }
    TRACE("instantiate %d (bad %d)", k, bad);
    Component c = F.instantiate(name, type, g, r, cb, 0, chance(50));
    if (bad && c) {
        violation("fmi2Instantiate with a bad argument returned an instance");
        F.free_instance(c);
        return;
    }
    if (!bad && !c) {
        violation("fmi2Instantiate returned NULL");
        return;
    }
    if (c) inst[k] = (Inst){c, INSTANTIATED, 0.0, INFINITY};
}

static void do_setup(Inst *in)
{
    int has_tol = chance(50), has_stop = chance(30);
    double start = chance(70) ? 0.0 : ODD[pick(N_ODD)];
    double stop = chance(50) ? start + 1.0 : ODD[pick(N_ODD)];
    double tol = chance(70) ? 1e-6 : ODD[pick(N_ODD)];
    TRACE("setup tol %d %g start %g stop %d %g", has_tol, tol, start, has_stop, stop);
    int s = status_ok(F.setup(in->c, has_tol, tol, start, has_stop, stop), "setupExperiment");
    int ok = in->phase == INSTANTIATED && isfinite(start) &&
             (!has_stop || (isfinite(stop) && stop >= start));
    if (!ok) forbidden(s, "fmi2SetupExperiment", "the phase or times are wrong");
    if (s <= 1 && ok) {
        in->time = start;
        in->stop = has_stop ? stop : INFINITY;
    }
}

static void do_enter(Inst *in)
{
    TRACE("enterInitializationMode");
    int s = status_ok(F.enter_init(in->c), "enterInitializationMode");
    if (in->phase != INSTANTIATED) forbidden(s, "fmi2EnterInitializationMode", PHASE[in->phase]);
    else if (s <= 1) in->phase = INITIALIZATION;
}

static void do_exit(Inst *in)
{
    TRACE("exitInitializationMode");
    int s = status_ok(F.exit_init(in->c), "exitInitializationMode");
    if (in->phase != INITIALIZATION) {
        forbidden(s, "fmi2ExitInitializationMode", PHASE[in->phase]);
    } else {
        in->phase = s <= 1 ? INITIALIZED : FAILED;
    }
}

static void do_step(Inst *in)
{
    double t = in->time, h = 0.01;
    switch (pick(12)) {
    case 0: t = ODD[pick(N_ODD)]; break;
    case 1: h = ODD[pick(N_ODD)]; break;
    case 2: t = in->time - 0.01; break;
    case 3: t = in->time + 1e-12; break;
    case 4: h = 1e-9; break;
    case 5: h = chance(50) ? 0.5 : 1e-300; break;
    default: break;
    }
    int no_set = (int)pick(3) - (chance(5) ? 5 : 0);
    TRACE("doStep t %.17g h %.17g (model time %.17g, %s)", t, h, in->time, PHASE[in->phase]);
    int s = status_ok(F.do_step(in->c, t, h, no_set), "doStep");
    double scale = fabs(in->time) > 1.0 ? fabs(in->time) : 1.0;
    double stop_scale = fabs(in->stop) > 1.0 ? fabs(in->stop) : 1.0;
    int ok = in->phase == INITIALIZED && isfinite(h) && h > 0 && isfinite(t) &&
             fabs(t - in->time) <= 1e-9 * scale && isfinite(t + h) &&
             t + h <= in->stop + 1e-9 * stop_scale;
    if (!ok) {
        forbidden(s, "fmi2DoStep", "the phase, step or communication point is wrong");
    } else if (s <= 1) {
        in->time = t + h;
    } else if (s == 4) {
        in->phase = FAILED;
    }
    double last = NAN;
    int r = status_ok(F.get_real_status(in->c, 2, &last), "getRealStatus");
    if (r <= 1 && !isfinite(last)) violation("fmi2LastSuccessfulTime = %g with status %d", last, r);
    if (r <= 1 && in->phase == INITIALIZED && last != in->time) {
        violation("fmi2LastSuccessfulTime = %.17g, the host's model says %.17g", last, in->time);
        in->time = last;
    }
}

static void do_terminate(Inst *in)
{
    TRACE("terminate");
    int s = status_ok(F.terminate(in->c), "terminate");
    if (in->phase != INITIALIZED) forbidden(s, "fmi2Terminate", PHASE[in->phase]);
    else if (s <= 1) in->phase = TERMINATED;
    else if (s >= 3) in->phase = s == 4 ? FAILED : in->phase;
}

static void do_reset(Inst *in)
{
    TRACE("reset");
    int s = status_ok(F.reset(in->c), "reset");
    if (s <= 1) *in = (Inst){in->c, INSTANTIATED, 0.0, INFINITY};
}

#define ROOM 600

static void do_get(Inst *in)
{
    static const char TYPES[] = "RIBS";
    char type = TYPES[pick(4)];
    size_t n = pick(100) < 10 ? 0 : 1 + pick(chance(20) ? ROOM : 5);
    static Vr vr[ROOM];
    static double reals[ROOM];
    static int ints[ROOM];
    static const char *texts[ROOM];
    int valid = 1;
    for (size_t i = 0; i < n; i++) {
        vr[i] = random_vr(type);
        const Var *v = var_of(vr[i]);
        if (!v || v->type != type) valid = 0;
        /* no value yet: an output computed in initialisation mode (no start value) */
        if (v && in->phase == INSTANTIATED && type != 'S' && isnan(v->start)) valid = 0;
    }
    int null_vr = chance(5), null_values = chance(5);
    void *values = type == 'R' ? (void *)reals : type == 'S' ? (void *)texts : (void *)ints;
    for (size_t i = 0; i < n; i++) reals[i] = 12345.0;
    TRACE("get%c n %zu valid %d nulls %d %d", type, n, valid, null_vr, null_values);
    const Vr *v = null_vr ? NULL : vr;
    void *out = null_values ? NULL : values;
    int s;
    if (type == 'R') s = F.get_real(in->c, v, n, out);
    else if (type == 'I') s = F.get_integer(in->c, v, n, out);
    else if (type == 'B') s = F.get_boolean(in->c, v, n, out);
    else s = F.get_string(in->c, v, n, out);
    status_ok(s, "get");
    if (n && (!valid || null_vr || null_values)) forbidden(s, "fmi2Get", "a bad argument");
    if (s <= 1 && type == 'R' && out) {
        for (size_t i = 0; i < n; i++) {
            if (!isfinite(reals[i])) {
                violation("getReal vr %u = %g with status %d", vr[i], reals[i], s);
            }
        }
    }
    if (s <= 1 && type == 'B' && out) {
        for (size_t i = 0; i < n; i++) {
            if (ints[i] != 0 && ints[i] != 1) violation("getBoolean vr %u = %d", vr[i], ints[i]);
        }
    }
    if (s <= 1 && type == 'S' && out) {
        for (size_t i = 0; i < n; i++) {
            if (!texts[i]) violation("getString vr %u = NULL with status %d", vr[i], s);
            else (void)strlen(texts[i]);
        }
    }
}

static void do_set(Inst *in)
{
    static const char TYPES[] = "RIBS";
    char type = TYPES[pick(4)];
    size_t n = pick(100) < 10 ? 0 : 1 + pick(chance(10) ? ROOM : 4);
    static Vr vr[ROOM];
    static double reals[ROOM];
    static int ints[ROOM];
    static const char *texts[ROOM];
    int valid = 1, maybe_any = 0;
    for (size_t i = 0; i < n; i++) {
        vr[i] = random_vr(type);
        const Var *v = var_of(vr[i]);
        double x;
        if (type == 'R') x = reals[i] = random_real(v);
        else if (type == 'I') x = ints[i] = chance(20) ? (chance(50) ? INT_MIN : INT_MAX)
                                                       : (int)pick(5) - 1;
        else if (type == 'B') x = ints[i] = chance(20) ? -7 : (int)pick(2);
        else {
            texts[i] = chance(3) ? NULL : random_string();
            x = NAN;
        }
        int maybe;
        if (type == 'B') x = x != 0;
        if (!writable(in, v, type, x, &maybe)) valid = 0;
        if (type == 'S' && !texts[i]) valid = 0;
        maybe_any |= maybe;
    }
    int null_vr = chance(5), null_values = chance(5);
    TRACE("set%c n %zu valid %d nulls %d %d (%s)", type, n, valid, null_vr, null_values,
          PHASE[in->phase]);
    const Vr *v = null_vr ? NULL : vr;
    int s;
    if (type == 'R') s = F.set_real(in->c, v, n, null_values ? NULL : reals);
    else if (type == 'I') s = F.set_integer(in->c, v, n, null_values ? NULL : ints);
    else if (type == 'B') s = F.set_boolean(in->c, v, n, null_values ? NULL : ints);
    else s = F.set_string(in->c, v, n, null_values ? NULL : texts);
    status_ok(s, "set");
    if (n && (null_vr || null_values)) forbidden(s, "fmi2Set", "a NULL array");
    else if (n && !valid && !maybe_any) forbidden(s, "fmi2Set", "a write FMI forbids now");
}

/* Strings read and written straight back (the pointers fmi2GetString returned, valid until
 * the next call), a variable twice in one call among them, after a new value of it. */
static void do_strings_back(Inst *in)
{
    Vr vr[4];
    const char *texts[4];
    size_t n = 0;
    for (size_t i = 0; i < nvars && n < 1; i++) {
        if (vars[i].type == 'S' && chance(70)) vr[n++] = vars[i].vr;
    }
    if (!n) return;
    TRACE("getString then setString back");
    if (status_ok(F.get_string(in->c, vr, 1, texts), "getString") > 1 || !texts[0]) return;
    vr[1] = vr[0];
    vr[2] = vr[0];
    texts[2] = texts[0]; /* read back after the new value replaced it */
    texts[1] = chance(50) ? "remus100" : "[[0, 0, 5], [100, 0, 5]]";
    int maybe;
    const Var *v = var_of(vr[0]);
    int s = status_ok(F.set_string(in->c, vr, 3, texts), "setString");
    if (!writable(in, v, 'S', NAN, &maybe) && !maybe) forbidden(s, "fmi2SetString", "a write");
}

static void do_derivatives(Inst *in)
{
    size_t n = pick(4);
    Vr vr[4];
    int order[4];
    double values[4];
    int valid = interpolates && (in->phase == INITIALIZATION || in->phase == INITIALIZED);
    static const int ORDERS[] = {1, 2, 0, 3, -1, INT_MIN, INT_MAX};
    for (size_t i = 0; i < n; i++) {
        vr[i] = random_vr('R');
        order[i] = chance(70) ? 1 + (int)pick(2) : ORDERS[pick(7)];
        values[i] = chance(80) ? (double)pick(3) : ODD[pick(N_ODD)];
        const Var *v = var_of(vr[i]);
        if (!v || v->type != 'R' || strcmp(v->causality, "input") ||
            (order[i] != 1 && order[i] != 2) || !isfinite(values[i])) {
            valid = 0;
        }
    }
    int nulls = chance(5);
    TRACE("setRealInputDerivatives n %zu valid %d nulls %d", n, valid, nulls);
    int s = status_ok(F.set_derivatives(in->c, nulls ? NULL : vr, n, order, values),
                      "setRealInputDerivatives");
    if (n && (!valid || nulls)) forbidden(s, "fmi2SetRealInputDerivatives", "bad arguments");
}

static void do_get_state(Inst *in, int k)
{
    int j = (int)pick(STATES);
    SavedState *st = &states[j];
    int reuse = st->state && chance(50);
    if (st->state && !reuse) {
        TRACE("freeFMUstate %d", j);
        void *freed = st->state;
        status_ok(F.free_state(in->c, &st->state), "freeFMUstate");
        if (st->state) violation("fmi2FreeFMUstate left the pointer");
        if (hostile) graveyard[buried++ % 16] = freed;
        st->state = NULL;
        return;
    }
    if (chance(3)) {
        TRACE("getFMUstate NULL");
        forbidden(status_ok(F.get_state(in->c, NULL), "getFMUstate"), "fmi2GetFMUstate", "NULL");
        return;
    }
    TRACE("getFMUstate into %d (reuse %d)", j, reuse);
    void *before = st->state;
    int s = status_ok(F.get_state(in->c, &st->state), "getFMUstate");
    if (s <= 1) {
        if (!reuse) st->owner = k; /* a state taken again stays its first instance's */
        st->phase = in->phase;
        st->time = in->time;
    } else if (st->state != before) {
        violation("a failed fmi2GetFMUstate changed the pointer");
    }
}

static void do_set_state(Inst *in)
{
    int j = (int)pick(STATES);
    SavedState *st = &states[j];
    if (!st->state) {
        TRACE("setFMUstate NULL");
        forbidden(status_ok(F.set_state(in->c, NULL), "setFMUstate"), "fmi2SetFMUstate", "NULL");
        return;
    }
    TRACE("setFMUstate %d (%s at %g)", j, PHASE[st->phase], st->time);
    int s = status_ok(F.set_state(in->c, st->state), "setFMUstate");
    if (s > 1) violation("fmi2SetFMUstate refused a state this FMU took (%d)", s);
    if (s <= 1) {
        in->phase = st->phase;
        in->time = st->time;
    }
}

static void do_serialize(Inst *in)
{
    int j = (int)pick(STATES);
    SavedState *st = &states[j];
    if (!st->state) return;
    size_t size = 0;
    int null_size = chance(5);
    TRACE("serializedFMUstateSize %d", j);
    int s = status_ok(F.state_size(in->c, st->state, null_size ? NULL : &size), "stateSize");
    if (null_size) {
        forbidden(s, "fmi2SerializedFMUstateSize", "size is NULL");
        return;
    }
    if (s > 1) return;
    size_t room = size + 64;
    char *bytes = malloc(room);
    size_t given = size;
    switch (pick(8)) {
    case 0: given = 0; break;
    case 1: given = size - 1; break;
    case 2: given = size / 2; break;
    case 3: given = size + 64; break;
    default: break;
    }
    TRACE("serializeFMUstate %d size %zu given %zu", j, size, given);
    int null_bytes = chance(3);
    s = status_ok(F.serialize(in->c, st->state, null_bytes ? NULL : bytes, given), "serialize");
    if (given < size || null_bytes) {
        forbidden(s, "fmi2SerializeFMUstate", "the array is too small or NULL");
        free(bytes);
        return;
    }
    if (s <= 1) {
        free(blob);
        blob = bytes;
        blob_size = size;
        blob_phase = st->phase;
        blob_time = st->time;
    } else {
        free(bytes);
    }
}

static void do_deserialize(Inst *in)
{
    if (!blob) return;
    size_t n = blob_size;
    char *copy = malloc(blob_size + 16);
    memcpy(copy, blob, blob_size);
    int intact = 1;
    switch (pick(8)) {
    case 0: n = pick((unsigned)blob_size); intact = n == blob_size; break;
    case 1: memset(copy + blob_size, 0, 16); n = blob_size + 1 + pick(15); intact = 0; break;
    case 2: copy[pick((unsigned)blob_size)] ^= (char)(1 << pick(8)); intact = 0; break;
    default: break;
    }
    int j = (int)pick(STATES);
    SavedState *st = &states[j];
    if (st->state) {
        status_ok(F.free_state(in->c, &st->state), "freeFMUstate");
        st->state = NULL;
    }
    TRACE("deSerializeFMUstate %zu of %zu bytes (intact %d) into %d", n, blob_size, intact, j);
    int null_state = chance(3);
    int s = status_ok(F.deserialize(in->c, copy, n, null_state ? NULL : &st->state),
                      "deserialize");
    if (!intact || null_state) {
        if (s <= 1 && !null_state) {
            /* a changed byte the CRC cannot see is impossible; cut or extended too */
            violation("fmi2DeSerializeFMUstate accepted changed bytes");
        }
        forbidden(s, "fmi2DeSerializeFMUstate", "the bytes are changed or the pointer NULL");
    } else if (s > 1) {
        violation("fmi2DeSerializeFMUstate refused intact bytes (%d)", s);
    }
    if (s <= 1 && st->state) {
        st->owner = current;
        st->phase = blob_phase;
        st->time = blob_time;
    }
    free(copy);
}

/* Pointers no FMU state is: a state freed before, a small block of the host's own, a
 * pointer into a String literal, an odd address. Each must be refused (never read). */

static void do_hostile_state(Inst *in)
{
    static char small[3];
    void *pointers[] = {graveyard[pick(16)], small, (void *)"not a state", (void *)(uintptr_t)8,
                        (void *)(uintptr_t)0x7fff0000u};
    int which = (int)pick(5);
    void *p = pointers[which];
    if (!p) return;
    void *copy = p;
    size_t size = 0;
    char bytes[64];
    TRACE("hostile state %d (%p)", which, p);
    int s;
    const char *call;
    switch (pick(5)) {
    case 0: s = F.set_state(in->c, p), call = "fmi2SetFMUstate"; break;
    case 1: s = F.free_state(in->c, &copy), call = "fmi2FreeFMUstate"; break;
    case 2: s = F.state_size(in->c, p, &size), call = "fmi2SerializedFMUstateSize"; break;
    case 3: s = F.serialize(in->c, p, bytes, sizeof bytes), call = "fmi2SerializeFMUstate"; break;
    default: s = F.get_state(in->c, &copy), call = "fmi2GetFMUstate";
    }
    forbidden(status_ok(s, call), call, "not a state");
}

static void do_status(Inst *in)
{
    int kind = chance(80) ? (int)pick(4) : (chance(50) ? -1 : 99);
    int null = chance(10);
    int iv = -99, bv = -99, sv = -99;
    double rv = NAN;
    const char *text = NULL;
    TRACE("status kind %d null %d", kind, null);
    switch (pick(5)) {
    case 0:
        sv = status_ok(F.get_status(in->c, kind, null ? NULL : &iv), "getStatus");
        if (sv <= 1 && !null && (iv < 0 || iv > 5)) violation("getStatus value %d", iv);
        break;
    case 1:
        sv = status_ok(F.get_real_status(in->c, kind, null ? NULL : &rv), "getRealStatus");
        if (sv <= 1 && (null || kind != 2)) violation("getRealStatus kind %d null %d", kind, null);
        if (sv <= 1 && !isfinite(rv)) violation("getRealStatus %g OK", rv);
        break;
    case 2:
        sv = status_ok(F.get_integer_status(in->c, kind, null ? NULL : &iv), "getIntegerStatus");
        break;
    case 3:
        sv = status_ok(F.get_boolean_status(in->c, kind, null ? NULL : &bv), "getBooleanStatus");
        if (sv <= 1 && (null || kind != 3)) {
            violation("getBooleanStatus kind %d null %d", kind, null);
        }
        break;
    default:
        sv = status_ok(F.get_string_status(in->c, kind, null ? NULL : &text), "getStringStatus");
        break;
    }
}

static void do_misc(Inst *in)
{
    static const char *const CATEGORIES[] = {"logAll", "logStatusError", "nope", NULL, ""};
    const char *list[3];
    size_t n = pick(4);
    for (size_t i = 0; i < n && i < 3; i++) list[i] = CATEGORIES[pick(5)];
    if (n > 3) n = 3;
    double out[4];
    Vr vr[2] = {0, 1};
    int order[2] = {1, 1};
    switch (pick(4)) {
    case 0:
        TRACE("setDebugLogging n %zu", n);
        status_ok(F.debug_logging(in->c, (int)pick(2), n, chance(10) ? NULL : list), "debug");
        break;
    case 1:
        TRACE("cancelStep");
        forbidden(status_ok(F.cancel(in->c), "cancelStep"), "fmi2CancelStep", "nothing pending");
        break;
    case 2:
        TRACE("getRealOutputDerivatives");
        forbidden(status_ok(F.get_derivatives(in->c, vr, 2, order, out), "outputDerivatives"),
                  "fmi2GetRealOutputDerivatives", "maxOutputDerivativeOrder is 0");
        break;
    default:
        TRACE("getDirectionalDerivative");
        forbidden(status_ok(F.directional(in->c, vr, 1, vr + 1, 1, out, out + 1), "directional"),
                  "fmi2GetDirectionalDerivative", "not provided");
    }
}

#define LOAD(field, name) *(void **)&F.field = need(library, name)

static void load(const char *dir, const char *id)
{
    char path[4200], text[65536];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        printf("dlopen failed: %s\n", dlerror());
        exit(2);
    }
    LOAD(instantiate, "fmi2Instantiate");
    LOAD(free_instance, "fmi2FreeInstance");
    LOAD(setup, "fmi2SetupExperiment");
    LOAD(enter_init, "fmi2EnterInitializationMode");
    LOAD(exit_init, "fmi2ExitInitializationMode");
    LOAD(terminate, "fmi2Terminate");
    LOAD(reset, "fmi2Reset");
    LOAD(cancel, "fmi2CancelStep");
    LOAD(do_step, "fmi2DoStep");
    LOAD(get_real, "fmi2GetReal");
    LOAD(set_real, "fmi2SetReal");
    LOAD(get_integer, "fmi2GetInteger");
    LOAD(set_integer, "fmi2SetInteger");
    LOAD(get_boolean, "fmi2GetBoolean");
    LOAD(set_boolean, "fmi2SetBoolean");
    LOAD(get_string, "fmi2GetString");
    LOAD(set_string, "fmi2SetString");
    LOAD(get_state, "fmi2GetFMUstate");
    LOAD(set_state, "fmi2SetFMUstate");
    LOAD(free_state, "fmi2FreeFMUstate");
    LOAD(state_size, "fmi2SerializedFMUstateSize");
    LOAD(serialize, "fmi2SerializeFMUstate");
    LOAD(deserialize, "fmi2DeSerializeFMUstate");
    LOAD(set_derivatives, "fmi2SetRealInputDerivatives");
    LOAD(get_derivatives, "fmi2GetRealOutputDerivatives");
    LOAD(directional, "fmi2GetDirectionalDerivative");
    LOAD(get_status, "fmi2GetStatus");
    LOAD(get_real_status, "fmi2GetRealStatus");
    LOAD(get_integer_status, "fmi2GetIntegerStatus");
    LOAD(get_boolean_status, "fmi2GetBooleanStatus");
    LOAD(get_string_status, "fmi2GetStringStatus");
    LOAD(debug_logging, "fmi2SetDebugLogging");
    read_description(dir, text, sizeof text, guid);
    interpolates = strstr(text, "canInterpolateInputs=\"true\"") != NULL;
    snprintf(resources, sizeof resources, "file://%s/resources", dir);
}

int main(int argc, char **argv)
{
    setvbuf(stdout, NULL, _IOLBF, 0);
    if (argc < 5) {
        fprintf(stderr, "usage: fuzz_host DIR ID SEED OPS [verbose] [hostile]\n");
        return 2;
    }
    load(argv[1], argv[2]);
    read_variables(argv[1]);
    rng ^= strtoull(argv[3], NULL, 10) * 0x9E3779B97F4A7C15ull;
    if (!rng) rng = 1;
    long ops = atol(argv[4]);
    for (int i = 5; i < argc; i++) {
        if (!strcmp(argv[i], "verbose")) verbose = 1;
        if (!strcmp(argv[i], "hostile")) hostile = 1;
    }
    for (op = 0; op < ops; op++) {
        int k = slot_of_live();
        if (k < 0 || chance(3)) {
            do_instantiate(k < 0 ? (int)pick(INSTANCES) : (int)pick(INSTANCES));
            continue;
        }
        Inst *in = &inst[k];
        current = k;
        /* mostly the FMI sequence, sometimes anything */
        unsigned what = pick(100);
        if (what < 6) do_setup(in);
        else if (what < 12) do_enter(in);
        else if (what < 18) do_exit(in);
        else if (what < 40) do_step(in);
        else if (what < 43) do_terminate(in);
        else if (what < 45) do_reset(in);
        else if (what < 57) do_get(in);
        else if (what < 69) do_set(in);
        else if (what < 72) do_derivatives(in);
        else if (what < 74) do_strings_back(in);
        else if (what < 80) do_get_state(in, k);
        else if (what < 85) do_set_state(in);
        else if (what < 89) do_serialize(in);
        else if (what < 93) do_deserialize(in);
        else if (what < 96) do_status(in);
        else if (what < 97) { if (hostile) do_hostile_state(in); }
        else do_misc(in);
    }
    for (int j = 0; j < STATES; j++) {
        int k = slot_of_live();
        if (states[j].state && k >= 0) F.free_state(inst[k].c, &states[j].state);
    }
    for (int k = 0; k < INSTANCES; k++) {
        if (inst[k].c) F.free_instance(inst[k].c);
    }
    free(blob);
    printf("fuzz: %ld ops, %d violations\n", ops, violations);
    return violations ? 1 : 0;
}
