/* A minimal FMI 2.0 co-simulation host in C, compiled by the tests: what a non-Python tool
 * (a C/C++ master, a command-line program) does with one of our FMUs.
 *
 *   fmi_host DIR ID cycles N STEPS  N times: instantiate, initialise, STEPS doSteps of
 *                                   10 ms, terminate, free; prints "cycles: N x STEPS ok"
 *   fmi_host DIR ID illegal         each call FMI 2.0 forbids, on a fresh instance;
 *                                   prints "<case> <status>" per case, then whether a
 *                                   valid call still works after the refusals (and
 *                                   whether a parameter is read before initialisation)
 *   fmi_host DIR ID hostile         NULL arguments FMI hosts pass, wrong GUIDs, and value
 *                                   counts and state sizes too large for any array:
 *                                   prints "<case> <status>" (or NULL / instance for
 *                                   fmi2Instantiate), then a valid step after them
 *   fmi_host DIR ID twice DIR2      one build extracted twice (DIR, DIR2), an instance of
 *                                   each, stepped in turn: prints "<case> <status>"
 *   fmi_host DIR ID race DIR2       the first instances in the process of two extractions
 *                                   (two copies of the runtime), instantiated at once from
 *                                   two threads, then initialised and stepped there:
 *                                   prints "race: S1 S2" (the worst status of each, 9 for
 *                                   NULL from fmi2Instantiate)
 *   fmi_host DIR ID abandon         instantiate, initialise, step, then exit without
 *                                   terminating or freeing; prints "abandoned"
 *   fmi_host DIR ID gil             instantiate and initialise (the runtime starts
 *                                   Python), take Python's GIL in this thread, and have a
 *                                   second thread get and set every Real, Integer and
 *                                   String variable meanwhile: prints "values without the
 *                                   GIL: N calls, worst status S", or "blocked" when the
 *                                   second thread is still waiting after 60 s
 *   fmi_host DIR ID state           step 30, save and serialise the FMU state, step 30
 *                                   more; a second instance deserialises it, is set to
 *                                   it and steps the same 30: prints "state: identical
 *                                   over N outputs" or the first value that differs
 *   fmi_host DIR ID threads         as a parallel master (libcosim's worker threads) does:
 *                                   one instance stepped alone, then two instantiated here
 *                                   and stepped at once from two threads, and one
 *                                   instantiated, stepped and freed in a thread of its
 *                                   own: prints "threads: identical over N outputs" or
 *                                   the first value that differs from the lone run
 *   fmi_host DIR ID corrupt         a serialised state changed at 64 places, cut and
 *                                   extended: prints "corrupt: A of N accepted"
 *   fmi_host DIR ID strays          pointers that are no FMU state (one freed before, a
 *                                   block of the host's own, a String literal, an odd
 *                                   address) given to each FMU state function: prints
 *                                   "<case> <status>", then whether a state still
 *                                   round-trips
 *   fmi_host DIR ID strings-back    a String read and written straight back (the
 *                                   pointer fmi2GetString returned, valid until the next
 *                                   call): after another value in the same call, then
 *                                   once initialised (a fixed parameter given the value it
 *                                   has); prints "<case> <status>" and "<case>-value TEXT"
 *   fmi_host DIR ID unfreed         FMU states a host never frees: an instance takes
 *                                   three (one deserialised), a second instance frees one
 *                                   of them, the first is freed with the other two alive,
 *                                   then the second sets one of those: prints "unfreed:
 *                                   free-through-other S set-after-free S"
 *   fmi_host DIR ID uri URI         instantiated with URI as its resource location,
 *                                   initialised, 30 doSteps: prints "uri:" and its Real
 *                                   outputs (%.17g)
 *
 * DIR is the FMU's extraction folder, ID its model identifier. It loads
 * DIR/binaries/linux64/ID.so with dlopen and nothing else: no Python, no preload.
 */
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "fmi2_callbacks.h"

typedef void *Component;

typedef struct {
    Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *,
                             int, int);
    void (*free_instance)(Component);
    int (*setup)(Component, int, double, double, int, double);
    int (*enter_init)(Component);
    int (*exit_init)(Component);
    int (*do_step)(Component, double, double, int);
    int (*terminate)(Component);
    int (*get_real)(Component, const Vr *, size_t, double *);
    int (*set_real)(Component, const Vr *, size_t, const double *);
    int (*get_integer)(Component, const Vr *, size_t, int *);
    int (*set_integer)(Component, const Vr *, size_t, const int *);
    int (*set_boolean)(Component, const Vr *, size_t, const int *);
    int (*get_string)(Component, const Vr *, size_t, const char **);
    int (*set_string)(Component, const Vr *, size_t, const char *const *);
    int (*get_state)(Component, void **);
    int (*set_state)(Component, void *);
    int (*free_state)(Component, void **);
    int (*state_size)(Component, void *, size_t *);
    int (*serialize)(Component, void *, char *, size_t);
    int (*deserialize)(Component, const char *, size_t, void **);
    char guid[128], resources[4200], dir[4096];
} Fmu;

static int quiet;

static void logger(void *env, const char *name, int status, const char *category,
                   const char *message, ...)
{
    (void)env;
    if (quiet && status < 3) return;
    char text[4096];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message, args);
    va_end(args);
    printf("log %s [%d] {%s} %s\n", name ? name : "(null)", status,
           category ? category : "(null)", text);
}

static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};

static void load(Fmu *f, const char *dir, const char *id)
{
    char path[4200], text[65536];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        printf("dlopen failed: %s\n", dlerror());
        exit(2);
    }
    *(void **)&f->instantiate = need(library, "fmi2Instantiate");
    *(void **)&f->free_instance = need(library, "fmi2FreeInstance");
    *(void **)&f->setup = need(library, "fmi2SetupExperiment");
    *(void **)&f->enter_init = need(library, "fmi2EnterInitializationMode");
    *(void **)&f->exit_init = need(library, "fmi2ExitInitializationMode");
    *(void **)&f->do_step = need(library, "fmi2DoStep");
    *(void **)&f->terminate = need(library, "fmi2Terminate");
    *(void **)&f->get_real = need(library, "fmi2GetReal");
    *(void **)&f->set_real = need(library, "fmi2SetReal");
    *(void **)&f->get_integer = need(library, "fmi2GetInteger");
    *(void **)&f->set_integer = need(library, "fmi2SetInteger");
    *(void **)&f->set_boolean = need(library, "fmi2SetBoolean");
    *(void **)&f->get_string = need(library, "fmi2GetString");
    *(void **)&f->set_string = need(library, "fmi2SetString");
    *(void **)&f->get_state = need(library, "fmi2GetFMUstate");
    *(void **)&f->set_state = need(library, "fmi2SetFMUstate");
    *(void **)&f->free_state = need(library, "fmi2FreeFMUstate");
    *(void **)&f->state_size = need(library, "fmi2SerializedFMUstateSize");
    *(void **)&f->serialize = need(library, "fmi2SerializeFMUstate");
    *(void **)&f->deserialize = need(library, "fmi2DeSerializeFMUstate");
    read_description(dir, text, sizeof text, f->guid);
    snprintf(f->resources, sizeof f->resources, "file://%s/resources", dir);
    snprintf(f->dir, sizeof f->dir, "%s", dir);
}

static Component start(const Fmu *f, int initialise)
{
    Component c = f->instantiate("host", 1, f->guid, f->resources, &callbacks, 0, 1);
    if (!c) {
        printf("instantiate returned NULL\n");
        exit(3);
    }
    if (initialise && (f->setup(c, 0, 0.0, 0.0, 0, 0.0) || f->enter_init(c) || f->exit_init(c))) {
        printf("initialisation failed\n");
        exit(3);
    }
    return c;
}

static void stop(const Fmu *f, Component c)
{
    f->terminate(c);
    f->free_instance(c);
}

static int cycles(const Fmu *f, int n, int steps)
{
    quiet = 1;
    for (int k = 0; k < n; k++) {
        Component c = start(f, 1);
        for (int i = 0; i < steps; i++) {
            int s = f->do_step(c, i * 0.01, 0.01, 1);
            if (s != 0) {
                printf("cycle %d step %d: status %d\n", k, i, s);
                return 1;
            }
        }
        stop(f, c);
    }
    printf("cycles: %d x %d ok\n", n, steps);
    return 0;
}

static size_t variables(const Fmu *f, const char *type, const char *causality, Vr *vrs,
                        size_t room);

/* The first variable in resources/fmu_variables.txt matching a type, causality and
 * variability ("*" for any) that declares a min or max if ``bounded``: its vr, start and a
 * value just outside its range. */
static int find(const Fmu *f, const char *type, const char *causality, const char *variability,
                int bounded, Vr *vr, double *start, double *outside)
{
    char path[4300], line[512], t[4], ca[32], va[32], lo[40], hi[40], st[40], name[128];
    snprintf(path, sizeof path, "%s/fmu_variables.txt", f->resources + 7);
    FILE *in = fopen(path, "r");
    int found = 0;
    while (in && !found && fgets(line, sizeof line, in)) {
        if (sscanf(line, "%u %3s %31s %31s %39s %39s %39s %127s", vr, t, ca, va, lo, hi, st,
                   name) == 8 &&
            !strcmp(t, type) && (!strcmp(causality, "*") || !strcmp(ca, causality)) &&
            (!strcmp(variability, "*") || !strcmp(va, variability)) &&
            (!bounded || strcmp(hi, "-") || strcmp(lo, "-"))) {
            *start = strtod(st, NULL);
            *outside = strcmp(hi, "-") ? strtod(hi, NULL) + 1.0 : strtod(lo, NULL) - 1.0;
            found = 1;
        }
    }
    if (in) fclose(in);
    return found;
}

/* The first Real output without a start value (initial="calculated"): 1 with its vr. */
static int unstarted_output(const Fmu *f, Vr *vr)
{
    char path[4300], line[512], t[4], ca[32], va[32], lo[40], hi[40], st[40];
    snprintf(path, sizeof path, "%s/fmu_variables.txt", f->resources + 7);
    FILE *in = fopen(path, "r");
    int found = 0;
    while (in && !found && fgets(line, sizeof line, in)) {
        found = sscanf(line, "%u %3s %31s %31s %39s %39s %39s", vr, t, ca, va, lo, hi, st) == 7 &&
                !strcmp(t, "R") && !strcmp(ca, "output") && !strcmp(st, "-");
    }
    if (in) fclose(in);
    return found;
}

static int worse(int worst, int status) { return status > worst ? status : worst; }

static void illegal_sequence(const Fmu *f)
{
    Component c = start(f, 0);
    printf("terminate-before-initialisation %d\n", f->terminate(c));
    f->setup(c, 0, 0.0, 0.0, 0, 0.0);
    f->enter_init(c);
    printf("second-enterInitializationMode %d\n", f->enter_init(c));
    printf("terminate-in-initialisation-mode %d\n", f->terminate(c));
    f->free_instance(c);

    c = start(f, 0);
    printf("doStep-before-initialisation %d\n", f->do_step(c, 0.0, 0.01, 1));
    Vr out, parameter;
    double x = 0.0;
    if (unstarted_output(f, &out)) { /* it has no value before initialisation mode */
        printf("getReal-output-before-initialisation %d\n", f->get_real(c, &out, 1, &x));
    }
    if (variables(f, "R", "parameter", &parameter, 1) == 1) { /* its start value */
        printf("getReal-parameter-before-initialisation %d\n",
               f->get_real(c, &parameter, 1, &x));
    }
    f->free_instance(c);

    c = start(f, 1);
    f->do_step(c, 0.0, 0.01, 1);
    printf("doStep-at-wrong-point %d\n", f->do_step(c, 0.5, 0.01, 1));
    printf("valid-step-after-refusals %d\n", f->do_step(c, 0.01, 0.01, 1));
    printf("valid-terminate-after-refusals %d\n", f->terminate(c));
    printf("second-terminate %d\n", f->terminate(c));
    f->free_instance(c);
}

static int illegal(const Fmu *f)
{
    illegal_sequence(f);
    Vr vr;
    double start_value, outside;
    Component c = start(f, 1);
    if (find(f, "R", "parameter", "fixed", 0, &vr, &start_value, &outside)) {
        double changed = start_value + 1.0;
        printf("setReal-fixed-parameter-after-initialisation %d\n",
               f->set_real(c, &vr, 1, &changed));
    }
    stop(f, c);

    c = start(f, 0);
    f->setup(c, 0, 0.0, 0.0, 0, 0.0);
    f->enter_init(c);
    if (find(f, "I", "*", "*", 1, &vr, &start_value, &outside)) {
        int value = (int)outside;
        printf("setInteger-outside-range %d\n", f->set_integer(c, &vr, 1, &value));
    }
    if (find(f, "R", "*", "*", 1, &vr, &start_value, &outside)) {
        printf("setReal-outside-range %d\n", f->set_real(c, &vr, 1, &outside));
    }
    printf("valid-initialisation-after-refusals %d\n", f->exit_init(c));
    stop(f, c);

    c = start(f, 0);
    printf("setupExperiment-stop-before-start %d\n", f->setup(c, 0, 0.0, 1.0, 1, 0.5));
    printf("valid-setup-after-refusals %d\n", f->setup(c, 0, 0.0, 0.0, 1, 0.03));
    f->enter_init(c);
    f->exit_init(c);
    int worst = 0;
    for (int i = 0; i < 3; i++) worst = worse(worst, f->do_step(c, i * 0.01, 0.01, 1));
    printf("valid-steps-to-stop-time %d\n", worst);
    printf("doStep-past-stop-time %d\n", f->do_step(c, 0.03, 0.01, 1));
    stop(f, c);
    return 0;
}

static void instantiations(const Fmu *f)
{
    const char *cases[][3] = {
        {"instantiate-null-name", NULL, f->guid},
        {"instantiate-null-guid", "host", NULL},
        {"instantiate-wrong-guid", "host", "{00000000-0000-0000-0000-000000000000}"},
    };
    for (int i = 0; i < 3; i++) {
        Component c = f->instantiate(cases[i][1], 1, cases[i][2], f->resources, &callbacks, 0, 1);
        printf("%s %s\n", cases[i][0], c ? "instance" : "NULL");
        if (c) f->free_instance(c);
    }
    Component c = f->instantiate("host", 1, f->guid, NULL, &callbacks, 0, 1);
    printf("instantiate-null-resources %s\n", c ? "instance" : "NULL");
    if (c) f->free_instance(c);
}

static int hostile(const Fmu *f)
{
    instantiations(f);
    Component c = start(f, 1);
    Vr vr = 0;
    double real = 0.0;
    int integer = 0;
    const char *text = NULL;
    void *state = NULL;
    printf("getReal-null-references %d\n", f->get_real(c, NULL, 1, &real));
    printf("getReal-null-values %d\n", f->get_real(c, &vr, 1, NULL));
    printf("setReal-null-references %d\n", f->set_real(c, NULL, 1, &real));
    printf("setReal-null-values %d\n", f->set_real(c, &vr, 1, NULL));
    printf("getInteger-null-references %d\n", f->get_integer(c, NULL, 1, &integer));
    printf("getInteger-null-values %d\n", f->get_integer(c, &vr, 1, NULL));
    printf("setInteger-null-references %d\n", f->set_integer(c, NULL, 1, &integer));
    printf("setInteger-null-values %d\n", f->set_integer(c, &vr, 1, NULL));
    printf("getString-null-values %d\n", f->get_string(c, &vr, 1, NULL));
    printf("setString-null-values %d\n", f->set_string(c, &vr, 1, NULL));
    printf("setString-null-string %d\n", f->set_string(c, &vr, 1, &text));
    printf("deSerialize-null-bytes %d\n", f->deserialize(c, NULL, 64, &state));
    printf("deSerialize-null-state %d\n", f->deserialize(c, "0123456789abcdef", 16, NULL));
    printf("getFMUstate-null-state %d\n", f->get_state(c, NULL));
    /* a count whose doubles overflow size_t (8 bytes each): two values given, the count
     * a host computed wrongly; refused before any value past the two is read */
    Vr two[2];
    int values[2] = {0, 0};
    size_t wrapping = (size_t)-1 / sizeof(double) + 2;
    if (variables(f, "I", "parameter", two, 1) == 1) {
        two[1] = two[0];
        printf("setInteger-count-overflow %d\n", f->set_integer(c, two, wrapping, values));
    }
    if (variables(f, "B", "parameter", two, 1) == 1) {
        two[1] = two[0];
        printf("setBoolean-count-overflow %d\n", f->set_boolean(c, two, wrapping, values));
    }
    if (f->get_state(c, &state) == 0) {
        printf("serialize-null-bytes %d\n", f->serialize(c, state, NULL, 64));
        /* a state's true bytes with a size no array can have (over 2^63): a host's
         * arithmetic gone wrong; refused before a byte past the true ones is read */
        size_t size = 0;
        char *bytes = NULL;
        if (!f->state_size(c, state, &size) && (bytes = malloc(size)) &&
            !f->serialize(c, state, bytes, size)) {
            void *loaded = NULL;
            size_t huge = ((size_t)1 << 63) + size;
            printf("deSerialize-size-past-any-array %d\n",
                   f->deserialize(c, bytes, huge, &loaded));
        }
        free(bytes);
        f->free_state(c, &state);
    }
    printf("valid-step-after-refusals %d\n", f->do_step(c, 0.0, 0.01, 1));
    stop(f, c);
    return 0;
}

static int twice(const Fmu *first, const char *dir, const char *id)
{
    Fmu second;
    load(&second, dir, id);
    const Fmu *fmus[2] = {first, &second};
    Component c[2];
    for (int k = 0; k < 2; k++) { /* the second made while the first is initialising */
        c[k] = start(fmus[k], 0);
        printf("setup-%d %d\n", k, fmus[k]->setup(c[k], 0, 0, 0, 0, 0));
        printf("enter-%d %d\n", k, fmus[k]->enter_init(c[k]));
    }
    for (int k = 0; k < 2; k++) printf("exit-%d %d\n", k, fmus[k]->exit_init(c[k]));
    int worst = 0;
    for (int i = 0; i < 50; i++) {
        for (int k = 0; k < 2; k++) {
            int s = fmus[k]->do_step(c[k], i * 0.01, 0.01, 1);
            worst = s > worst ? s : worst;
        }
    }
    printf("steps %d\n", worst);
    for (int k = 0; k < 2; k++) stop(fmus[k], c[k]);
    return 0;
}

typedef struct {
    Fmu f;
    int status;
} Racer;

/* The first instance of its extraction: instantiated, initialised, stepped and freed. */
static void *race_one(void *data)
{
    Racer *r = data;
    Component c = r->f.instantiate("host", 1, r->f.guid, r->f.resources, &callbacks, 0, 0);
    if (!c) {
        r->status = 9;
        return NULL;
    }
    r->status = r->f.setup(c, 0, 0.0, 0.0, 0, 0.0); /* in this order: one call a line */
    r->status = worse(r->status, r->f.enter_init(c));
    r->status = worse(r->status, r->f.exit_init(c));
    r->status = worse(r->status, r->f.do_step(c, 0.0, 0.01, 1));
    stop(&r->f, c);
    return NULL;
}

static int race(const Fmu *first, const char *dir, const char *id)
{
    static Racer racers[2];
    racers[0].f = *first;
    load(&racers[1].f, dir, id);
    quiet = 1;
    pthread_t threads[2];
    for (int k = 0; k < 2; k++) pthread_create(&threads[k], NULL, race_one, &racers[k]);
    for (int k = 0; k < 2; k++) pthread_join(threads[k], NULL);
    printf("race: %d %d\n", racers[0].status, racers[1].status);
    return 0;
}

static int abandon(const Fmu *f)
{
    Component c = start(f, 1);
    for (int i = 0; i < 5; i++) f->do_step(c, i * 0.01, 0.01, 1);
    printf("abandoned\n");
    return 0; /* exit() with the instance alive, never terminated */
}

/* Every variable of ``type`` (and causality, "*" for any) in resources/fmu_variables.txt:
 * their value references into ``vrs`` (at most ``room``), their number returned. */
static size_t variables(const Fmu *f, const char *type, const char *causality, Vr *vrs,
                        size_t room)
{
    char path[4300], line[512], t[4], ca[32];
    snprintf(path, sizeof path, "%s/fmu_variables.txt", f->resources + 7);
    FILE *in = fopen(path, "r");
    size_t n = 0;
    Vr vr;
    while (in && n < room && fgets(line, sizeof line, in)) {
        if (sscanf(line, "%u %3s %31s", &vr, t, ca) == 3 && !strcmp(t, type) &&
            (!strcmp(causality, "*") || !strcmp(ca, causality))) {
            vrs[n++] = vr;
        }
    }
    if (in) fclose(in);
    return n;
}

typedef struct {
    const Fmu *f;
    Component c;
    int calls, worst;
    volatile int done;
} Reader;

/* Gets and sets of every Real, Integer and String: the values a host exchanges. */
static void *read_and_write(void *data)
{
    Reader *r = data;
    Vr reals[512], integers[64], strings[64], inputs[128];
    double x[512];
    int n_int[64];
    const char *text[64];
    size_t nr = variables(r->f, "R", "*", reals, 512);
    size_t ni = variables(r->f, "I", "*", integers, 64);
    size_t ns = variables(r->f, "S", "*", strings, 64);
    size_t nu = variables(r->f, "R", "input", inputs, 128);
    for (int k = 0; k < 100; k++) {
        r->worst = worse(r->worst, r->f->get_real(r->c, reals, nr, x));
        r->worst = worse(r->worst, r->f->get_integer(r->c, integers, ni, n_int));
        r->worst = worse(r->worst, r->f->get_string(r->c, strings, ns, text));
        r->worst = worse(r->worst, r->f->get_real(r->c, inputs, nu, x));
        r->worst = worse(r->worst, r->f->set_real(r->c, inputs, nu, x));
        r->calls += 5;
    }
    r->done = 1;
    return NULL;
}

static int gil(const Fmu *f)
{
    Component c = start(f, 1);
    int (*ensure)(void) = (int (*)(void))dlsym(RTLD_DEFAULT, "PyGILState_Ensure");
    void (*release)(int) = (void (*)(int))dlsym(RTLD_DEFAULT, "PyGILState_Release");
    if (!ensure || !release) {
        printf("no Python in the process\n");
        return 1;
    }
    int held = ensure();
    Reader r = {f, c, 0, 0, 0};
    pthread_t thread;
    pthread_create(&thread, NULL, read_and_write, &r);
    for (int i = 0; i < 6000 && !r.done; i++) {
        struct timespec pause = {0, 10000000}; /* 10 ms */
        nanosleep(&pause, NULL);
    }
    if (!r.done) { /* the other thread waits for this one's GIL: it never comes back */
        printf("blocked\n");
        _exit(1);
    }
    pthread_join(thread, NULL);
    release(held);
    printf("values without the GIL: %d calls, worst status %d\n", r.calls, r.worst);
    stop(f, c);
    return 0;
}

static int outputs(const Fmu *f, Component c, Vr *vrs, size_t n, double *rows, int steps,
                   double t0)
{
    for (int i = 0; i < steps; i++) {
        if (f->do_step(c, t0 + i * 0.01, 0.01, 0) || f->get_real(c, vrs, n, rows + i * n)) {
            return 1;
        }
    }
    return 0;
}

static int state(const Fmu *f)
{
    enum { STEPS = 30, ROOM = 256 };
    static double first[STEPS * ROOM], again[STEPS * ROOM];
    Vr vrs[ROOM];
    size_t n = variables(f, "R", "output", vrs, ROOM);
    Component c = start(f, 1);
    void *saved = NULL;
    size_t size = 0;
    if (outputs(f, c, vrs, n, first, STEPS, 0.0) || f->get_state(c, &saved) ||
        f->state_size(c, saved, &size)) {
        printf("could not save the state\n");
        return 1;
    }
    char *bytes = malloc(size);
    int s = f->serialize(c, saved, bytes, size);
    f->free_state(c, &saved);
    if (s || outputs(f, c, vrs, n, first, STEPS, STEPS * 0.01)) {
        printf("could not serialise the state\n");
        return 1;
    }
    Component other = start(f, 0);
    void *loaded = NULL;
    if (f->deserialize(other, bytes, size, &loaded) || f->set_state(other, loaded) ||
        outputs(f, other, vrs, n, again, STEPS, STEPS * 0.01)) {
        printf("could not restore the state\n");
        return 1;
    }
    for (size_t i = 0; i < STEPS * n; i++) {
        if (memcmp(&first[i], &again[i], sizeof(double))) {
            printf("differs: step %zu output vr %u: %.17g then %.17g\n", i / n, vrs[i % n],
                   first[i], again[i]);
            return 1;
        }
    }
    printf("state: identical over %zu outputs\n", n);
    f->free_state(other, &loaded);
    free(bytes);
    stop(f, other);
    stop(f, c);
    return 0;
}

enum { THREAD_STEPS = 300, THREAD_ROOM = 256 };

typedef struct {
    const Fmu *f;
    Component c; /* NULL: the thread instantiates, initialises and frees its own */
    Vr outs[THREAD_ROOM];
    size_t n;
    double rows[THREAD_STEPS * THREAD_ROOM];
    int status;
} Lane;

/* A state serialised after 10 steps, then, one at a time, a byte changed at 64 places
 * spread over it (the runtime's header, the value buffers, the slave's own part), the
 * last byte cut and a byte added: each deserialised and set; prints "corrupt: A of N
 * accepted" (A should be 0), then whether the intact bytes still restore. */
static int corrupt(const Fmu *f)
{
    enum { PLACES = 64 };
    Component c = start(f, 1);
    for (int i = 0; i < 10; i++) f->do_step(c, i * 0.01, 0.01, 1);
    void *saved = NULL;
    size_t size = 0;
    if (f->get_state(c, &saved) || f->state_size(c, saved, &size)) {
        printf("could not save the state\n");
        return 1;
    }
    char *bytes = malloc(size + 1), *copy = malloc(size + 1);
    if (!bytes || !copy || f->serialize(c, saved, bytes, size)) {
        printf("could not serialise the state\n");
        free(bytes);
        free(copy);
        return 1;
    }
    f->free_state(c, &saved);
    quiet = 1;
    int accepted = 0, tried = 0;
    for (int k = 0; k < PLACES + 2; k++) {
        memcpy(copy, bytes, size);
        size_t n = size;
        if (k < PLACES) copy[(size - 1) * (size_t)k / (PLACES - 1)] ^= 0x10;
        else if (k == PLACES) n = size - 1;
        else copy[n++] = ' ';
        void *loaded = NULL;
        tried++;
        if (!f->deserialize(c, copy, n, &loaded)) {
            if (!f->set_state(c, loaded)) accepted++;
            f->free_state(c, &loaded);
        }
    }
    quiet = 0;
    printf("corrupt: %d of %d accepted\n", accepted, tried);
    void *loaded = NULL;
    int s = f->deserialize(c, bytes, size, &loaded) || f->set_state(c, loaded);
    printf("intact-state-restores %d\n", s);
    f->free_state(c, &loaded);
    free(bytes);
    free(copy);
    stop(f, c);
    return 0;
}

/* Pointers that are no FMU state of this FMU, given to every function taking one: each
 * must be refused without being read (a freed block, the host's memory, an address). */
static int strays(const Fmu *f)
{
    static char small[3];
    Component c = start(f, 1);
    void *freed = NULL;
    if (f->get_state(c, &freed) || f->free_state(c, &freed)) {
        printf("could not take and free a state\n");
        return 1;
    }
    f->get_state(c, &freed); /* its block may be reused: taken and freed again below */
    void *again = freed;
    f->free_state(c, &again);
    void *pointers[] = {freed, small, (void *)"not a state", (void *)(size_t)16};
    const char *names[] = {"freed", "host-block", "literal", "address"};
    quiet = 1;
    for (int i = 0; i < 4; i++) {
        void *p = pointers[i], *q = pointers[i];
        size_t size = 0;
        char bytes[64];
        printf("setFMUstate-%s %d\n", names[i], f->set_state(c, p));
        printf("serializedFMUstateSize-%s %d\n", names[i], f->state_size(c, p, &size));
        printf("serializeFMUstate-%s %d\n", names[i], f->serialize(c, p, bytes, sizeof bytes));
        printf("getFMUstate-into-%s %d\n", names[i], f->get_state(c, &q));
        q = p;
        printf("freeFMUstate-%s %d\n", names[i], f->free_state(c, &q));
    }
    quiet = 0;
    void *state = NULL;
    int s = f->get_state(c, &state) || f->do_step(c, 0.0, 0.01, 0) || f->set_state(c, state) ||
            f->free_state(c, &state);
    printf("valid-state-after-refusals %d\n", s);
    stop(f, c);
    return 0;
}

/* The first String variable read, then written back with the pointer fmi2GetString gave:
 * after another value of it in the same call (the last value written wins), and after
 * initialisation alone (the value it has: taken). */
static int strings_back(const Fmu *f)
{
    Vr vr[2];
    if (variables(f, "S", "parameter", vr, 1) != 1) {
        printf("no String parameter\n");
        return 1;
    }
    vr[1] = vr[0];
    Component c = start(f, 0);
    const char *text = NULL, *after = NULL;
    char was[256];
    if (f->get_string(c, vr, 1, &text) || !text) {
        printf("could not read the String\n");
        return 1;
    }
    snprintf(was, sizeof was, "%s", text);
    const char *values[2] = {"another value", text};
    printf("setString-other-then-back %d\n", f->set_string(c, vr, 2, values));
    f->get_string(c, vr, 1, &after);
    printf("setString-other-then-back-value %s\n",
           after && !strcmp(after, was) ? "same" : "changed");
    if (f->setup(c, 0, 0.0, 0.0, 0, 0.0) || f->enter_init(c) || f->exit_init(c)) {
        printf("initialisation failed\n");
        return 1;
    }
    f->get_string(c, vr, 1, &text);
    printf("setString-back-after-initialisation %d\n", f->set_string(c, vr, 1, &text));
    f->get_string(c, vr, 1, &after);
    printf("setString-back-after-initialisation-value %s\n",
           after && !strcmp(after, was) ? "same" : "changed");
    stop(f, c);
    return 0;
}

/* Instantiated with ``uri`` as its fmuResourceLocation (not the host's own URI of DIR),
 * initialised and stepped 30 times: prints "uri:" and the Real outputs after the last step
 * (%.17g), or why it could not. */
static int with_uri(const Fmu *f, const char *uri)
{
    enum { STEPS = 30, ROOM = 256 };
    static double rows[STEPS * ROOM];
    static Fmu g;
    g = *f;
    snprintf(g.resources, sizeof g.resources, "%s", uri);
    Vr vrs[ROOM];
    size_t n = variables(f, "R", "output", vrs, ROOM);
    Component c = start(&g, 1);
    if (outputs(f, c, vrs, n, rows, STEPS, 0.0)) {
        printf("uri: a step failed\n");
        return 1;
    }
    printf("uri:");
    for (size_t i = 0; i < n; i++) printf(" %.17g", rows[(STEPS - 1) * n + i]);
    printf("\n");
    stop(f, c);
    return 0;
}

/* Every Real input moved off its start, so that the outputs change from step to step. */
static int nudge_inputs(const Fmu *f, Component c)
{
    Vr inputs[128];
    double x[128];
    size_t n = variables(f, "R", "input", inputs, 128);
    if (f->get_real(c, inputs, n, x)) return 1;
    for (size_t i = 0; i < n; i++) x[i] += 0.01;
    return f->set_real(c, inputs, n, x);
}

static void *lane(void *data)
{
    Lane *l = data;
    int own = l->c == NULL;
    Component c = own ? start(l->f, 1) : l->c;
    l->status = nudge_inputs(l->f, c) || outputs(l->f, c, l->outs, l->n, l->rows, THREAD_STEPS, 0.0);
    if (own) stop(l->f, c);
    return NULL;
}

static int same_rows(const Lane *a, const Lane *b, const char *what)
{
    if (b->status) {
        printf("%s: a call failed\n", what);
        return 1;
    }
    for (size_t i = 0; i < THREAD_STEPS * a->n; i++) {
        if (memcmp(&a->rows[i], &b->rows[i], sizeof(double))) {
            printf("%s differs: step %zu output vr %u: %.17g alone, %.17g\n", what, i / a->n,
                   a->outs[i % a->n], a->rows[i], b->rows[i]);
            return 1;
        }
    }
    return 0;
}

static int threads(const Fmu *f)
{
    quiet = 1;
    static Lane alone, first, second, own;
    Lane *lanes[] = {&alone, &first, &second, &own};
    for (int i = 0; i < 4; i++) {
        lanes[i]->f = f;
        lanes[i]->n = variables(f, "R", "output", lanes[i]->outs, THREAD_ROOM);
    }
    alone.c = start(f, 1);
    lane(&alone);
    if (alone.status) {
        printf("the lone instance failed\n");
        return 1;
    }
    first.c = start(f, 1);
    second.c = start(f, 1);
    pthread_t a, b, c;
    pthread_create(&a, NULL, lane, &first);
    pthread_create(&b, NULL, lane, &second);
    pthread_join(a, NULL);
    pthread_join(b, NULL);
    pthread_create(&c, NULL, lane, &own);
    pthread_join(c, NULL);
    if (same_rows(&alone, &first, "first of two threads") ||
        same_rows(&alone, &second, "second of two threads") ||
        same_rows(&alone, &own, "instance of its own thread")) {
        return 1;
    }
    stop(f, first.c);
    stop(f, second.c);
    stop(f, alone.c);
    printf("threads: identical over %zu outputs\n", alone.n);
    return 0;
}

static int unfreed(const Fmu *f)
{
    Component taker = start(f, 1), other = start(f, 1);
    void *states[3] = {NULL, NULL, NULL};
    size_t size = 0;
    if (f->get_state(taker, &states[0]) || f->get_state(taker, &states[1]) ||
        f->state_size(taker, states[0], &size)) {
        printf("could not save the states\n");
        return 1;
    }
    char *bytes = malloc(size);
    if (!bytes || f->serialize(taker, states[0], bytes, size) ||
        f->deserialize(taker, bytes, size, &states[2])) {
        printf("could not deserialise the state\n");
        return 1;
    }
    free(bytes);
    int through_other = f->free_state(other, &states[1]);
    stop(f, taker); /* states[0] and states[2] alive */
    int after_free = f->set_state(other, states[0]);
    stop(f, other);
    printf("unfreed: free-through-other %d set-after-free %d\n", through_other, after_free);
    return 0;
}

int main(int argc, char **argv)
{
    setvbuf(stdout, NULL, _IOLBF, 0);
    if (argc < 4) {
        fprintf(stderr, "usage: fmi_host DIR ID MODE [ARGS]\n");
        return 2;
    }
    Fmu f;
    load(&f, argv[1], argv[2]);
    const char *mode = argv[3];
    if (!strcmp(mode, "cycles") && argc == 6) return cycles(&f, atoi(argv[4]), atoi(argv[5]));
    if (!strcmp(mode, "illegal")) return illegal(&f);
    if (!strcmp(mode, "hostile")) return hostile(&f);
    if (!strcmp(mode, "twice") && argc == 5) return twice(&f, argv[4], argv[2]);
    if (!strcmp(mode, "race") && argc == 5) return race(&f, argv[4], argv[2]);
    if (!strcmp(mode, "abandon")) return abandon(&f);
    if (!strcmp(mode, "gil")) return gil(&f);
    if (!strcmp(mode, "state")) return state(&f);
    if (!strcmp(mode, "threads")) return threads(&f);
    if (!strcmp(mode, "uri") && argc == 5) return with_uri(&f, argv[4]);
    if (!strcmp(mode, "corrupt")) return corrupt(&f);
    if (!strcmp(mode, "strays")) return strays(&f);
    if (!strcmp(mode, "strings-back")) return strings_back(&f);
    if (!strcmp(mode, "unfreed")) return unfreed(&f);
    fprintf(stderr, "unknown mode %s\n", mode);
    return 2;
}
