/* An FMI 2.0 host in C that checks what our FMUs hand its logger, as a host that shows
 * an FMU's messages through printf (OMSimulator, libcosim, ecos, the Reference FMUs'
 * fmusim) relies on:
 *
 *   log_host DIR ID contract NAME   one instance named NAME: fmi2SetDebugLogging with no
 *                                   category, a declared one, an unknown one (with a %
 *                                   in it) and a long non-ASCII unknown one; a vehicle
 *                                   name with printf conversions in it, which makes the
 *                                   initialisation fail; prints "<case> <status>" per
 *                                   call and "log [S] {CATEGORY} TEXT" per message
 *   log_host DIR ID volume STEPS    instances "loud" (logging on) and "quiet" (logging
 *                                   off), initialised and stepped STEPS times (10 ms),
 *                                   then one refused call on "quiet" only, then freed:
 *                                   prints "<instance> <phase> N" (messages logged)
 *   log_host DIR ID silent          an instance given no logger (a NULL pointer in the
 *                                   callbacks), refused an unknown log category with %
 *                                   in it: prints "silent <status>"; the FMU writes the
 *                                   message to stderr itself
 *
 * Every message is checked: the instance name is the one the host gave, whole; the
 * status is fmi2OK .. fmi2Fatal; the category is one of the model description's
 * LogCategories; the message is a printf format with no conversion (every % doubled),
 * UTF-8, and ends in no line break. A message that breaks a rule prints "VIOLATION: ..."
 * and is not formatted (a %s in it would read an argument that is not there).
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_callbacks.h"
#include "log_rules.h"

typedef void *Component;

static char description[65536], expected_name[4096];
static int counts[2]; /* messages per instance: "loud"/NAME, "quiet" */

/* 1 if ``text`` is UTF-8 (no stray continuation byte, no sequence cut short). */
static int is_utf8(const char *text)
{
    const unsigned char *p = (const unsigned char *)text;
    while (*p) {
        int more = *p < 0x80 ? 0 : (*p & 0xE0) == 0xC0 ? 1 : (*p & 0xF0) == 0xE0 ? 2
                 : (*p & 0xF8) == 0xF0 ? 3 : -1;
        if (more < 0) return 0;
        for (p++; more > 0; more--, p++) {
            if ((*p & 0xC0) != 0x80) return 0;
        }
    }
    return 1;
}

static const char *broken_rule(const char *name, int status, const char *category,
                               const char *message)
{
    size_t n = message ? strlen(message) : 0;
    if (!name || (strcmp(name, expected_name) && strcmp(name, "quiet"))) {
        return "another instance name (or NULL)";
    }
    if (status < 0 || status > 4) return "a status outside fmi2OK .. fmi2Fatal";
    if (!category || !declared_in(description, category)) {
        return "a category the FMU does not declare";
    }
    if (!message || !is_utf8(message)) return "a message that is NULL or not UTF-8";
    if (!no_conversion(message)) return "a message with a printf conversion in it";
    if (n && (message[n - 1] == '\n' || message[n - 1] == '\r')) return "a line break at its end";
    return NULL;
}

static void logger(void *env, const char *name, int status, const char *category,
                   const char *message, ...)
{
    (void)env;
    const char *broken = broken_rule(name, status, category, message);
    counts[name && !strcmp(name, "quiet")]++;
    if (broken) {
        printf("VIOLATION: %s (status %d, category %s)\n", broken, status,
               category && is_utf8(category) ? category : "?");
        return;
    }
    va_list args;
    va_start(args, message);
    print_message(status, category, message, args);
    va_end(args);
}

typedef struct {
    Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *,
                             int, int);
    void (*free_instance)(Component);
    int (*debug)(Component, int, size_t, const char *const *);
    int (*setup)(Component, int, double, double, int, double);
    int (*enter_init)(Component);
    int (*exit_init)(Component);
    int (*do_step)(Component, double, double, int);
    int (*terminate)(Component);
    int (*set_string)(Component, const Vr *, size_t, const char *const *);
    int (*set_real)(Component, const Vr *, size_t, const double *);
    char guid[128], resources[4200];
} Fmu;

static void load(Fmu *f, const char *dir, const char *id)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        printf("dlopen failed: %s\n", dlerror());
        exit(2);
    }
    *(void **)&f->instantiate = need(library, "fmi2Instantiate");
    *(void **)&f->free_instance = need(library, "fmi2FreeInstance");
    *(void **)&f->debug = need(library, "fmi2SetDebugLogging");
    *(void **)&f->setup = need(library, "fmi2SetupExperiment");
    *(void **)&f->enter_init = need(library, "fmi2EnterInitializationMode");
    *(void **)&f->exit_init = need(library, "fmi2ExitInitializationMode");
    *(void **)&f->do_step = need(library, "fmi2DoStep");
    *(void **)&f->terminate = need(library, "fmi2Terminate");
    *(void **)&f->set_string = need(library, "fmi2SetString");
    *(void **)&f->set_real = need(library, "fmi2SetReal");
    read_description(dir, description, sizeof description, f->guid);
    snprintf(f->resources, sizeof f->resources, "file://%s/resources", dir);
}

static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};

static Component start(const Fmu *f, const char *name, const Callbacks *cb, int logging_on)
{
    Component c = f->instantiate(name, 1, f->guid, f->resources, cb, 0, logging_on);
    if (!c) {
        printf("instantiate returned NULL\n");
        exit(3);
    }
    return c;
}

/* The value reference of the variable ``name`` (given with its quotes), or exit 2. */
static Vr reference(const char *name)
{
    const char *at = strstr(description, name);
    const char *vr = at ? strstr(at, "valueReference=\"") : NULL;
    if (!vr) {
        printf("no variable %s\n", name);
        exit(2);
    }
    return (Vr)strtoul(vr + 16, NULL, 10);
}

static int contract(const Fmu *f, const char *name)
{
    snprintf(expected_name, sizeof expected_name, "%s", name);
    Component c = start(f, name, &callbacks, 1);
    const char *known[] = {"logStatusError", "logAll"}, *unknown[] = {"log%sEvents 100%"};
    char wide[200] = ""; /* 66 bytes of three-byte characters, then more */
    for (int i = 0; i < 40; i++) strcat(wide, "\xe2\x82\xac");
    const char *long_unknown[] = {wide};
    printf("none %d\n", f->debug(c, 1, 0, NULL));
    printf("declared %d\n", f->debug(c, 1, 2, known));
    printf("unknown %d\n", f->debug(c, 1, 1, unknown));
    printf("long-unknown %d\n", f->debug(c, 1, 1, long_unknown));
    Vr vehicle = reference("name=\"vehicle\"");
    const char *value[] = {"%s%n%d 100% \xc3\xa4"};
    printf("vehicle %d\n", f->set_string(c, &vehicle, 1, value));
    f->setup(c, 0, 0.0, 0.0, 0, 0.0);
    f->enter_init(c);
    printf("exit-init %d\n", f->exit_init(c));
    f->free_instance(c);
    return 0;
}

static int volume(const Fmu *f, int steps)
{
    snprintf(expected_name, sizeof expected_name, "loud");
    Component loud = start(f, "loud", &callbacks, 1), quiet = start(f, "quiet", &callbacks, 0);
    Component both[] = {loud, quiet};
    /* 10 m deep: a buoyant hull starting at the surface leaves the water within the steps,
     * which the plant says once (a Warning), and these steps are to log nothing */
    Vr down_0 = reference("name=\"down_0\"");
    const double deep = 10.0;
    for (int i = 0; i < 2; i++) {
        f->set_real(both[i], &down_0, 1, &deep);
        f->setup(both[i], 0, 0.0, 0.0, 0, 0.0);
        f->enter_init(both[i]);
        f->exit_init(both[i]);
    }
    printf("loud instantiate+init %d\nquiet instantiate+init %d\n", counts[0], counts[1]);
    counts[0] = counts[1] = 0;
    for (int k = 0; k < steps; k++) {
        for (int i = 0; i < 2; i++) f->do_step(both[i], k * 0.01, 0.01, 1);
    }
    printf("loud steps %d\nquiet steps %d\n", counts[0], counts[1]);
    counts[0] = counts[1] = 0;
    printf("quiet refused %d\n", f->setup(quiet, 0, 0.0, 0.0, 0, 0.0));
    printf("loud after-refusal %d\nquiet after-refusal %d\n", counts[0], counts[1]);
    counts[0] = counts[1] = 0;
    for (int i = 0; i < 2; i++) {
        f->terminate(both[i]);
        f->free_instance(both[i]);
    }
    printf("loud free %d\nquiet free %d\n", counts[0], counts[1]);
    return 0;
}

static int silent(const Fmu *f)
{
    static const Callbacks no_logger = {NULL, calloc, free, NULL, NULL};
    Component c = start(f, "silent", &no_logger, 1);
    const char *unknown[] = {"log%sEvents 100%"};
    printf("silent %d\n", f->debug(c, 1, 1, unknown));
    fflush(stderr);
    f->free_instance(c);
    return 0;
}

int main(int argc, char **argv)
{
    setvbuf(stdout, NULL, _IOLBF, 0);
    if (argc < 4) {
        fprintf(stderr, "usage: log_host DIR ID MODE [ARG]\n");
        return 2;
    }
    Fmu f;
    load(&f, argv[1], argv[2]);
    const char *mode = argv[3];
    if (!strcmp(mode, "contract") && argc == 5) return contract(&f, argv[4]);
    if (!strcmp(mode, "volume") && argc == 5) return volume(&f, atoi(argv[4]));
    if (!strcmp(mode, "silent")) return silent(&f);
    fprintf(stderr, "unknown mode %s\n", mode);
    return 2;
}
