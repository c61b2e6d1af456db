/* A portable FMI 2.0 co-simulation host that steps one FMU and prints its outputs, compiled
 * for Linux (cc, dlopen) and for Windows (zig cc -target x86_64-windows-gnu, LoadLibraryA)
 * from this one file, so that the same calls, in the same order, run on both:
 *
 *   stepper LIBRARY RESOURCE_URI GUID STEPS H SETS OUTS
 *
 * instantiates (co-simulation, logging off), sets up an experiment from 0, writes SETS
 * ("vr=value,vr=value": Real inputs) in initialisation mode, exits it, calls
 * fmi2SetRealInputDerivatives once (first-order derivative 0 of the first input of SETS:
 * what a master that extrapolates does; the runtime takes it, pythonfmu's DLL refuses it),
 * then takes STEPS steps of H seconds, printing after each "t v1 v2 ..." with the Real
 * values of OUTS ("vr,vr,...") in %.17g, and terminates and frees. Each log line the FMU
 * sends is printed as "LOG status category: message"; "derivatives S" is the status of
 * fmi2SetRealInputDerivatives, "exit S" the worst status of the rest.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _WIN32
#include <windows.h>
#define SYMBOL(lib, name) ((void *)GetProcAddress((HMODULE)(lib), name))
#else
#include <dlfcn.h>
#define SYMBOL(lib, name) dlsym(lib, name)
#endif

#include "fmi2_callbacks.h"
typedef void *(*Instantiate)(const char *, int, const char *, const char *, const Callbacks *,
                             int, int);
typedef int (*Setup)(void *, int, double, double, int, double);
typedef int (*Component)(void *);
typedef int (*DoStep)(void *, double, double, int);
typedef int (*Reals)(void *, const Vr *, size_t, double *);
typedef int (*SetReals)(void *, const Vr *, size_t, const double *);
typedef int (*Derivatives)(void *, const Vr *, size_t, const int *, const double *);
typedef void (*FreeInstance)(void *);

static void logger(void *env, const char *name, int status, const char *category,
                   const char *message, ...)
{
    (void)env, (void)name;
    char text[4096];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message, args);
    va_end(args);
    printf("LOG %d %s: %s\n", status, category ? category : "(null)", text);
    fflush(stdout);
}

static size_t parse(const char *list, Vr *vrs, double *values, size_t most)
{
    size_t n = 0;
    const char *p = list;
    while (*p && n < most) {
        char *end;
        vrs[n] = (Vr)strtoul(p, &end, 10);
        if (values) values[n] = strtod(end + 1, &end);
        n++;
        p = *end ? end + 1 : end;
    }
    return n;
}

static int worst(int a, int b) { return a > b ? a : b; }

int main(int argc, char **argv)
{
    if (argc != 8) {
        fprintf(stderr, "usage: stepper LIBRARY RESOURCE_URI GUID STEPS H SETS OUTS\n");
        return 2;
    }
#ifdef _WIN32
    void *lib = (void *)LoadLibraryA(argv[1]);
#else
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
#endif
    if (!lib) {
        printf("load failed\n");
        return 1;
    }
    Instantiate instantiate = (Instantiate)SYMBOL(lib, "fmi2Instantiate");
    Setup setup = (Setup)SYMBOL(lib, "fmi2SetupExperiment");
    Component enter = (Component)SYMBOL(lib, "fmi2EnterInitializationMode");
    Component leave = (Component)SYMBOL(lib, "fmi2ExitInitializationMode");
    Component terminate = (Component)SYMBOL(lib, "fmi2Terminate");
    DoStep step = (DoStep)SYMBOL(lib, "fmi2DoStep");
    Reals get = (Reals)SYMBOL(lib, "fmi2GetReal");
    SetReals set = (SetReals)SYMBOL(lib, "fmi2SetReal");
    Derivatives derivatives = (Derivatives)SYMBOL(lib, "fmi2SetRealInputDerivatives");
    FreeInstance release = (FreeInstance)SYMBOL(lib, "fmi2FreeInstance");
    Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    void *c = instantiate("stepper", 1, argv[3], argv[2], &callbacks, 0, 0);
    if (!c) {
        printf("instance NULL\n");
        return 1;
    }
    int steps = atoi(argv[4]);
    double h = strtod(argv[5], NULL);
    Vr sets[64], outs[256];
    double values[64], out[256];
    size_t n_sets = parse(argv[6], sets, values, 64);
    size_t n_outs = parse(argv[7], outs, NULL, 256);
    int status = setup(c, 0, 0.0, 0.0, 0, 0.0);
    status = worst(status, enter(c));
    status = worst(status, set(c, sets, n_sets, values));
    status = worst(status, leave(c));
    const int order = 1;
    const double zero = 0.0;
    printf("derivatives %d\n", derivatives(c, sets, n_sets ? 1 : 0, &order, &zero));
    for (int i = 1; i <= steps; i++) {
        status = worst(status, step(c, (i - 1) * h, h, 1));
        status = worst(status, get(c, outs, n_outs, out));
        printf("%.17g", i * h);
        for (size_t k = 0; k < n_outs; k++) printf(" %.17g", out[k]);
        printf("\n");
    }
    status = worst(status, terminate(c));
    release(c);
    printf("exit %d\n", status);
    fflush(stdout);
    return 0;
}
