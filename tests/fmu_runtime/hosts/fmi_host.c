/* A minimal FMI 2.0 co-simulation host in C, compiled by the tests: what a non-Python tool
 * (a C/C++ master, a command-line program) does with one of our FMUs.
 *
 *   fmi_host DIR ID cycles N STEPS   N times: instantiate, initialise, STEPS doSteps of
 *                                    10 ms, terminate, free; prints "cycles: N x STEPS ok"
 *   fmi_host DIR ID illegal          each call FMI 2.0 forbids, on a fresh instance;
 *                                    prints "<case> <status>" per case, then whether a
 *                                    valid step still works after the refusals
 *
 * DIR is the FMU's extraction folder, ID its model identifier. It loads
 * DIR/binaries/linux64/ID.so with dlopen and nothing else: no Python, no preload.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void *Component;
typedef unsigned int Vr;
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocate)(size_t, size_t);
    void (*release)(void *);
    void *step_finished;
    void *environment;
} Callbacks;

static Component (*instantiate)(const char *, int, const char *, const char *,
                                const Callbacks *, int, int);
static void (*free_instance)(Component);
static int (*setup)(Component, int, double, double, int, double);
static int (*enter_init)(Component);
static int (*exit_init)(Component);
static int (*do_step)(Component, double, double, int);
static int (*terminate)(Component);
static int (*set_real)(Component, const Vr *, size_t, const double *);
static int (*set_integer)(Component, const Vr *, size_t, const int *);

static char guid[128], resources[4200];
static int quiet;

static void logger(void *env, const char *name, int status, const char *category,
                   const char *message, ...)
{
    (void)env, (void)category;
    if (quiet && status < 3) return;
    char text[2048];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message, args);
    va_end(args);
    printf("log %s [%d] %s\n", name, status, text);
}

static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};

static void *need(void *library, const char *name)
{
    void *f = dlsym(library, name);
    if (!f) {
        printf("missing %s\n", name);
        exit(2);
    }
    return f;
}

static void load(const char *dir, const char *id)
{
    char path[4200], text[65536];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        printf("dlopen failed: %s\n", dlerror());
        exit(2);
    }
    instantiate = need(library, "fmi2Instantiate");
    free_instance = need(library, "fmi2FreeInstance");
    setup = need(library, "fmi2SetupExperiment");
    enter_init = need(library, "fmi2EnterInitializationMode");
    exit_init = need(library, "fmi2ExitInitializationMode");
    do_step = need(library, "fmi2DoStep");
    terminate = need(library, "fmi2Terminate");
    set_real = need(library, "fmi2SetReal");
    set_integer = need(library, "fmi2SetInteger");
    snprintf(path, sizeof path, "%s/modelDescription.xml", dir);
    FILE *md = fopen(path, "r");
    size_t n = md ? fread(text, 1, sizeof text - 1, md) : 0;
    if (md) fclose(md);
    text[n] = '\0';
    char *g = strstr(text, "guid=\"");
    if (g) sscanf(g + 6, "%127[^\"]", guid);
    snprintf(resources, sizeof resources, "file://%s/resources", dir);
}

static Component start(int initialise)
{
    Component c = instantiate("host", 1, guid, resources, &callbacks, 0, 1);
    if (!c) {
        printf("instantiate returned NULL\n");
        exit(3);
    }
    if (initialise && (setup(c, 0, 0.0, 0.0, 0, 0.0) || enter_init(c) || exit_init(c))) {
        printf("initialisation failed\n");
        exit(3);
    }
    return c;
}

static void stop(Component c)
{
    terminate(c);
    free_instance(c);
}

static int cycles(int n, int steps)
{
    quiet = 1;
    for (int k = 0; k < n; k++) {
        Component c = start(1);
        for (int i = 0; i < steps; i++) {
            int s = do_step(c, i * 0.01, 0.01, 1);
            if (s != 0) {
                printf("cycle %d step %d: status %d\n", k, i, s);
                return 1;
            }
        }
        stop(c);
    }
    printf("cycles: %d x %d ok\n", n, steps);
    return 0;
}

/* The first variable in resources/fmu_variables.txt matching a type, causality and
 * variability ("*" for any) that declares a min or max if ``bounded``: its vr, start and a
 * value just outside its range. */
static int find(const char *type, const char *causality, const char *variability, int bounded,
                Vr *vr, double *start, double *outside)
{
    char path[4300], line[512], t[4], ca[32], va[32], lo[40], hi[40], st[40], name[128];
    snprintf(path, sizeof path, "%s/fmu_variables.txt", resources + 7);
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

static int illegal(void)
{
    Component c = start(0);
    setup(c, 0, 0.0, 0.0, 0, 0.0);
    enter_init(c);
    printf("second-enterInitializationMode %d\n", enter_init(c));
    stop(c);

    c = start(0);
    printf("doStep-before-initialisation %d\n", do_step(c, 0.0, 0.01, 1));
    stop(c);

    c = start(1);
    do_step(c, 0.0, 0.01, 1);
    printf("doStep-at-wrong-point %d\n", do_step(c, 0.5, 0.01, 1));
    printf("valid-step-after-refusals %d\n", do_step(c, 0.01, 0.01, 1));
    stop(c);

    Vr vr;
    double start_value, outside;
    c = start(1);
    if (find("R", "parameter", "fixed", 0, &vr, &start_value, &outside)) {
        double changed = start_value + 1.0;
        printf("setReal-fixed-parameter-after-initialisation %d\n", set_real(c, &vr, 1, &changed));
    }
    stop(c);

    c = start(0);
    setup(c, 0, 0.0, 0.0, 0, 0.0);
    enter_init(c);
    if (find("I", "*", "*", 1, &vr, &start_value, &outside)) {
        int value = (int)outside;
        printf("setInteger-outside-range %d\n", set_integer(c, &vr, 1, &value));
    }
    if (find("R", "*", "*", 1, &vr, &start_value, &outside)) {
        printf("setReal-outside-range %d\n", set_real(c, &vr, 1, &outside));
    }
    printf("valid-initialisation-after-refusals %d\n", exit_init(c));
    stop(c);
    return 0;
}

int main(int argc, char **argv)
{
    setvbuf(stdout, NULL, _IOLBF, 0);
    if (argc < 4) {
        fprintf(stderr, "usage: fmi_host DIR ID cycles N STEPS | fmi_host DIR ID illegal\n");
        return 2;
    }
    load(argv[1], argv[2]);
    if (!strcmp(argv[3], "cycles") && argc == 6) return cycles(atoi(argv[4]), atoi(argv[5]));
    if (!strcmp(argv[3], "illegal")) return illegal();
    fprintf(stderr, "unknown mode %s\n", argv[3]);
    return 2;
}
