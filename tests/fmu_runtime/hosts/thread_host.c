/* A multi-threaded FMI 2.0 host in C, compiled by the tests: what a parallel master
 * (libcosim's worker pool, OMSimulator's parallel master) does with our FMUs. Barriers
 * force the interleavings; every run is compared, bit for bit, with the same instances
 * stepped one after the other in the main thread afterwards.
 *
 *   thread_host pair DIR1 ID1 DIR2 ID2 STEPS
 *       the first two instances in the process (DIR1 may be DIR2: two instances of one
 *       FMU) instantiated at once from two threads (logging on: the logger is called from
 *       both), initialised and stepped STEPS times there with their Real outputs read and
 *       their Real inputs set between steps, then freed at once: prints "pair: identical
 *       over N steps" or the first value that differs
 *   thread_host handoff DIR ID STEPS
 *       one instance instantiated in one thread, each step made by the next of three
 *       threads in turn (as a pool hands an instance to whichever worker is free), freed
 *       in another: prints "handoff: identical over N steps"
 *   thread_host states DIR ID ROUNDS
 *       two instances of one FMU stepped in two threads; each round, each thread takes an
 *       FMU state with its own instance, then frees the one the other thread took with its
 *       own instance while the other takes another (our FMUs let a state move between an
 *       FMU's instances): prints
 *       "states: N rounds, worst status S"
 *   thread_host late DIR ID LIBPYTHON
 *       the first instance in a process without Python made in one thread, held (the
 *       flock the runtime starts CPython under, on LIBPYTHON, taken here first) between
 *       loading CPython and initialising it, while a second thread makes another: prints
 *       "late: made (the second waited)", or "late: NULL ..." when one got no instance
 *
 * DIR is an FMU's extraction folder, ID its model identifier. The host loads
 * DIR/binaries/linux64/ID.so with dlopen and nothing else: no Python.
 */
#define _GNU_SOURCE /* RTLD_DEFAULT */
#include <dlfcn.h>
#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/syscall.h>
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
    int (*get_state)(Component, void **);
    int (*free_state)(Component, void **);
    char guid[128], resources[4200];
    Vr inputs[64], outputs[256];
    double starts[64];
    size_t n_in, n_out;
} Fmu;

enum { MAX_STEPS = 5000 };

typedef struct {
    const Fmu *f;
    Component c;
    int steps, status;
    double *rows; /* steps x n_out */
} Run;

static pthread_barrier_t barrier;

/* The logger a parallel master hands over: called from any of its threads. */
static void logger(void *env, const char *name, int status, const char *category,
                   const char *message, ...)
{
    (void)env;
    if (status < 3) return; /* OK and Warning lines: logged, not shown */
    char text[4096];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message, args);
    va_end(args);
    printf("log %s [%d] {%s} %s\n", name ? name : "(null)", status, category, text);
}

static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};

/* The Real inputs (with their starts) and Real outputs of resources/fmu_variables.txt. */
static void read_variables(Fmu *f, const char *dir)
{
    char path[4200], line[512], type[4], causality[32], start[40];
    unsigned vr;
    snprintf(path, sizeof path, "%s/resources/fmu_variables.txt", dir);
    FILE *in = fopen(path, "r");
    while (in && fgets(line, sizeof line, in)) {
        if (sscanf(line, "%u %3s %31s %*s %*s %*s %39s", &vr, type, causality, start) != 4 ||
            strcmp(type, "R"))
            continue;
        if (!strcmp(causality, "input") && f->n_in < 64) {
            f->starts[f->n_in] = strtod(start, NULL);
            f->inputs[f->n_in++] = vr;
        } else if (!strcmp(causality, "output") && f->n_out < 256) {
            f->outputs[f->n_out++] = vr;
        }
    }
    if (in) fclose(in);
}

static void load(Fmu *f, const char *dir, const char *id)
{
    char path[4200], text[65536];
    memset(f, 0, sizeof *f);
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
    *(void **)&f->get_state = need(library, "fmi2GetFMUstate");
    *(void **)&f->free_state = need(library, "fmi2FreeFMUstate");
    read_description(dir, text, sizeof text, f->guid);
    snprintf(f->resources, sizeof f->resources, "file://%s/resources", dir);
    read_variables(f, dir);
}

static int worse(int a, int b) { return a > b ? a : b; }

/* A new instance, logging on, initialised at t = 0 s; NULL if that failed. */
static Component start(const Fmu *f)
{
    Component c = f->instantiate("host", 1, f->guid, f->resources, &callbacks, 0, 1);
    if (c && (f->setup(c, 0, 0.0, 0.0, 0, 0.0) || f->enter_init(c) || f->exit_init(c))) {
        f->free_instance(c);
        return NULL;
    }
    return c;
}

/* Step ``k`` (10 ms from t = k * 10 ms): the inputs set from their starts and k, the
 * step, the outputs read into row k. */
static int step(Run *r, int k)
{
    const Fmu *f = r->f;
    double in[64];
    for (size_t i = 0; i < f->n_in; i++) in[i] = f->starts[i] + 0.001 * (k % 7);
    int s = f->set_real(r->c, f->inputs, f->n_in, in);
    s = worse(s, f->do_step(r->c, k * 0.01, 0.01, 1));
    return worse(s, f->get_real(r->c, f->outputs, f->n_out, r->rows + (size_t)k * f->n_out));
}

static void stop(Run *r)
{
    r->status = worse(r->status, r->f->terminate(r->c));
    r->f->free_instance(r->c);
}

/* One lane of ``pair``: instantiated, stepped and freed, each phase started at once with
 * the other lane's. */
static void *lane(void *data)
{
    Run *r = data;
    pthread_barrier_wait(&barrier);
    r->c = start(r->f);
    r->status = r->c ? 0 : 9;
    pthread_barrier_wait(&barrier);
    for (int k = 0; r->c && k < r->steps; k++) r->status = worse(r->status, step(r, k));
    pthread_barrier_wait(&barrier);
    if (r->c) stop(r);
    return NULL;
}

/* The same instance's run made in this thread alone; 0 if it equals ``r`` bit for bit. */
static int same_alone(const Run *r, const char *what)
{
    Run alone = {r->f, NULL, r->steps, 0, calloc((size_t)r->steps * r->f->n_out, sizeof(double))};
    alone.c = start(r->f);
    for (int k = 0; alone.c && k < alone.steps; k++) alone.status = worse(alone.status, step(&alone, k));
    if (!alone.c || alone.status > 1 || r->status > 1) {
        printf("%s: status %d, alone %d\n", what, r->status, alone.c ? alone.status : 9);
        free(alone.rows);
        return 1;
    }
    stop(&alone);
    for (size_t i = 0; i < (size_t)r->steps * r->f->n_out; i++) {
        if (memcmp(&alone.rows[i], &r->rows[i], sizeof(double))) {
            printf("%s differs: step %zu output vr %u: %.17g alone, %.17g\n", what,
                   i / r->f->n_out, r->f->outputs[i % r->f->n_out], alone.rows[i], r->rows[i]);
            free(alone.rows);
            return 1;
        }
    }
    free(alone.rows);
    return 0;
}

static int pair(const char *dirs[2], const char *ids[2], int steps)
{
    static Fmu fmus[2];
    Run runs[2];
    pthread_t threads[2];
    pthread_barrier_init(&barrier, NULL, 2);
    for (int k = 0; k < 2; k++) {
        load(&fmus[k], dirs[k], ids[k]);
        runs[k] = (Run){&fmus[k], NULL, steps, 0, calloc((size_t)steps * fmus[k].n_out, sizeof(double))};
    }
    for (int k = 0; k < 2; k++) pthread_create(&threads[k], NULL, lane, &runs[k]);
    for (int k = 0; k < 2; k++) pthread_join(threads[k], NULL);
    if (same_alone(&runs[0], "first") || same_alone(&runs[1], "second")) return 1;
    printf("pair: identical over %d steps\n", steps);
    return 0;
}

enum { POOL = 3 };

typedef struct {
    Run *run;
    int index; /* this worker makes the steps k with k % POOL == index */
} Worker;

/* One worker of ``handoff``: instantiates (worker 0), makes its steps, frees (the last). */
static void *worker(void *data)
{
    Worker *w = data;
    Run *r = w->run;
    if (w->index == 0) r->c = start(r->f);
    pthread_barrier_wait(&barrier);
    for (int k = 0; r->c && k < r->steps; k++) {
        if (k % POOL == w->index) r->status = worse(r->status, step(r, k));
        pthread_barrier_wait(&barrier); /* the next step is another worker's */
    }
    if (w->index == POOL - 1 && r->c) stop(r);
    return NULL;
}

static int handoff(const char *dir, const char *id, int steps)
{
    static Fmu f;
    load(&f, dir, id);
    Run run = {&f, NULL, steps, 0, calloc((size_t)steps * f.n_out, sizeof(double))};
    Worker workers[POOL];
    pthread_t threads[POOL];
    pthread_barrier_init(&barrier, NULL, POOL);
    for (int k = 0; k < POOL; k++) {
        workers[k] = (Worker){&run, k};
        pthread_create(&threads[k], NULL, worker, &workers[k]);
    }
    for (int k = 0; k < POOL; k++) pthread_join(threads[k], NULL);
    if (!run.c) {
        printf("handoff: instantiation failed\n");
        return 1;
    }
    if (same_alone(&run, "handed-off")) return 1;
    printf("handoff: identical over %d steps\n", steps);
    return 0;
}

typedef struct {
    Run *mine, *other;
    void **taken, **theirs; /* the state this thread takes, the one the other took */
    int rounds;
} Swapper;

/* One thread of ``states``: each round a step and a state taken with its own instance;
 * then, at once with the other thread, a second state taken with its own instance (the
 * other thread frees one of this instance's meanwhile) and the other's first state freed
 * with this instance; then its second freed. */
static void *swapper(void *data)
{
    Swapper *s = data;
    Run *r = s->mine;
    for (int k = 0; k < s->rounds; k++) {
        void *extra = NULL;
        r->status = worse(r->status, r->f->do_step(r->c, k * 0.01, 0.01, 1));
        r->status = worse(r->status, r->f->get_state(r->c, s->taken));
        pthread_barrier_wait(&barrier);
        r->status = worse(r->status, r->f->get_state(r->c, &extra));
        r->status = worse(r->status, r->f->free_state(r->c, s->theirs));
        pthread_barrier_wait(&barrier);
        r->status = worse(r->status, r->f->free_state(r->c, &extra));
    }
    return NULL;
}

static int states(const char *dir, const char *id, int rounds)
{
    static Fmu f;
    load(&f, dir, id);
    Run runs[2] = {{&f, start(&f), rounds, 0, NULL}, {&f, start(&f), rounds, 0, NULL}};
    void *taken[2] = {NULL, NULL};
    Swapper swappers[2] = {{&runs[0], &runs[1], &taken[0], &taken[1], rounds},
                           {&runs[1], &runs[0], &taken[1], &taken[0], rounds}};
    pthread_t threads[2];
    pthread_barrier_init(&barrier, NULL, 2);
    if (!runs[0].c || !runs[1].c) {
        printf("states: instantiation failed\n");
        return 1;
    }
    for (int k = 0; k < 2; k++) pthread_create(&threads[k], NULL, swapper, &swappers[k]);
    for (int k = 0; k < 2; k++) pthread_join(threads[k], NULL);
    stop(&runs[0]);
    stop(&runs[1]);
    printf("states: %d rounds, worst status %d\n", rounds, worse(runs[0].status, runs[1].status));
    return 0;
}

typedef struct {
    const Fmu *f;
    Component c;
    volatile pid_t tid; /* set before the thread calls fmi2Instantiate */
} Maker;

static void *make(void *data)
{
    Maker *m = data;
    m->tid = (pid_t)syscall(SYS_gettid);
    m->c = start(m->f);
    return NULL;
}

/* 1 once thread ``tid`` of this process sleeps (waits on a lock), polled for 60 s. */
static int waits(pid_t tid)
{
    char path[64], text[512];
    snprintf(path, sizeof path, "/proc/self/task/%d/stat", (int)tid);
    for (int i = 0; i < 6000; i++) {
        FILE *stat = fopen(path, "r");
        size_t n = stat ? fread(text, 1, sizeof text - 1, stat) : 0;
        if (stat) fclose(stat);
        text[n] = '\0';
        const char *state = strrchr(text, ')'); /* "pid (name) S ..." */
        if (state && state[1] == ' ' && state[2] == 'S') return 1;
        struct timespec pause = {0, 10000000}; /* 10 ms */
        nanosleep(&pause, NULL);
    }
    return 0;
}

static void *watchdog(void *data)
{
    volatile int *done = data;
    for (int i = 0; i < 12000 && !*done; i++) {
        struct timespec pause = {0, 10000000}; /* 10 ms */
        nanosleep(&pause, NULL);
    }
    if (!*done) { /* the GIL this thread holds and a lock the other holds: for ever */
        printf("blocked\n");
        _exit(1);
    }
    return NULL;
}

static int gil_held(const char *dirs[2], const char *ids[2])
{
    static Fmu fmus[2];
    for (int k = 0; k < 2; k++) load(&fmus[k], dirs[k], ids[k]);
    Component first = start(&fmus[0]);
    int (*ensure)(void) = (int (*)(void))dlsym(RTLD_DEFAULT, "PyGILState_Ensure");
    void (*release)(int) = (void (*)(int))dlsym(RTLD_DEFAULT, "PyGILState_Release");
    if (!first || !ensure || !release) {
        printf("gil-held: no instance, or no Python in the process\n");
        return 1;
    }
    static volatile int done;
    pthread_t dog, other;
    pthread_create(&dog, NULL, watchdog, (void *)&done);
    int held = ensure();
    Maker m = {&fmus[1], NULL, 0};
    pthread_create(&other, NULL, make, &m);
    while (!m.tid) sched_yield();
    int waited = waits(m.tid);
    Component mine = start(&fmus[1]);
    done = 1;
    release(held);
    pthread_join(other, NULL);
    pthread_join(dog, NULL);
    if (!waited || !mine || !m.c) {
        printf("gil-held: waited %d, made %d %d\n", waited, mine != NULL, m.c != NULL);
        return 1;
    }
    fmus[1].free_instance(mine);
    fmus[1].free_instance(m.c);
    fmus[0].free_instance(first);
    printf("gil-held: both made\n");
    return 0;
}

/* 1 once thread ``tid`` of this process is inside system call ``number`` (its
 * /proc/self/task/TID/syscall starts with it), 0 once ``*done`` is set instead; polled
 * every millisecond without a time limit (the test's own limit ends a host that hangs). */
static int in_syscall(pid_t tid, long number, volatile int *done)
{
    char path[64], text[256];
    snprintf(path, sizeof path, "/proc/self/task/%d/syscall", (int)tid);
    while (!*done) {
        FILE *file = fopen(path, "r");
        long now = -1;
        if (file && fgets(text, sizeof text, file)) now = strtol(text, NULL, 10);
        if (file) fclose(file);
        if (now == number) return 1;
        struct timespec pause = {0, 1000000}; /* 1 ms */
        nanosleep(&pause, NULL);
    }
    return 0;
}

typedef struct {
    const Fmu *f;
    Component c;
    volatile pid_t tid; /* set before the thread calls fmi2Instantiate */
    volatile int done;  /* set once it returned */
} Late;

static void *make_late(void *data)
{
    Late *m = data;
    m->tid = (pid_t)syscall(SYS_gettid);
    m->c = m->f->instantiate("late", 1, m->f->guid, m->f->resources, &callbacks, 0, 0);
    m->done = 1;
    return NULL;
}

/* The first instance's thread is held inside the runtime between loading CPython and
 * initialising it: this thread holds the lock the runtime initialises CPython under (an
 * flock on LIBPYTHON, which excludes another descriptor in this process too) until the
 * first thread waits for it, then starts the second instantiation, and lets go once that
 * one returned or waits on a lock itself (futex). No timing decides the interleaving. */
static int late(const char *dir, const char *id, const char *libpython)
{
    static Fmu f;
    load(&f, dir, id);
    int held = open(libpython, O_RDONLY | O_CLOEXEC);
    if (held < 0 || flock(held, LOCK_EX) != 0) {
        printf("late: cannot lock %s\n", libpython);
        return 2;
    }
    Late first = {&f, NULL, 0, 0}, second = {&f, NULL, 0, 0};
    pthread_t threads[2];
    pthread_create(&threads[0], NULL, make_late, &first);
    while (!first.tid) sched_yield();
    if (!in_syscall(first.tid, SYS_flock, &first.done)) {
        printf("late: the first instantiation never waited to start CPython (%s)\n",
               first.c ? "made" : "NULL");
        return 1;
    }
    pthread_create(&threads[1], NULL, make_late, &second);
    while (!second.tid) sched_yield();
    int waited = in_syscall(second.tid, SYS_futex, &second.done);
    flock(held, LOCK_UN);
    close(held);
    for (int k = 0; k < 2; k++) pthread_join(threads[k], NULL);
    printf("late: %s (the second %s)\n", second.c && first.c ? "made" : "NULL",
           waited ? "waited" : "returned at once");
    if (second.c) f.free_instance(second.c);
    if (first.c) f.free_instance(first.c);
    return second.c && first.c ? 0 : 1;
}

int main(int argc, char **argv)
{
    setvbuf(stdout, NULL, _IOLBF, 0);
    int steps = argc > 0 ? atoi(argv[argc - 1]) : 0;
    if (steps < 1 || steps > MAX_STEPS) steps = 0;
    if (argc == 7 && steps && !strcmp(argv[1], "pair")) {
        const char *dirs[2] = {argv[2], argv[4]}, *ids[2] = {argv[3], argv[5]};
        return pair(dirs, ids, steps);
    }
    if (argc == 5 && !strcmp(argv[1], "late")) return late(argv[2], argv[3], argv[4]);
    if (argc == 6 && !strcmp(argv[1], "gil-held")) {
        const char *dirs[2] = {argv[2], argv[4]}, *ids[2] = {argv[3], argv[5]};
        return gil_held(dirs, ids);
    }
    if (argc == 5 && steps && !strcmp(argv[1], "handoff")) return handoff(argv[2], argv[3], steps);
    if (argc == 5 && steps && !strcmp(argv[1], "states")) return states(argv[2], argv[3], steps);
    fprintf(stderr, "usage: thread_host pair DIR1 ID1 DIR2 ID2 STEPS | handoff DIR ID STEPS | "
                    "states DIR ID ROUNDS | late DIR ID LIBPYTHON | gil-held DIR1 ID1 DIR2 ID2\n");
    return 2;
}
