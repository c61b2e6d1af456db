/* The FMU's binary: FMI 2.0 co-simulation functions that enforce the standard's state
 * machine and the variables' declared rules, then forward to pythonfmu's wrapper library.
 *
 * Written by hand because pythonfmu's wrapper cannot do it: it returns fmi2OK from every
 * function but doStep whatever the Python side decides, and it needs its host to have
 * started Python (runtime.c does that here).
 *
 * Refused without calling Python, with fmi2Error, one Error logged and nothing changed:
 * a call out of the FMI 2.0 co-simulation sequence (instantiated -> initialisation mode ->
 * initialised -> terminated; the error state after a failed initialisation or a fatal
 * error); a doStep whose step is not a finite number > 0 or whose
 * currentCommunicationPoint is not the FMU's current time (the start time, then the end
 * of the last step) within a relative 1e-9; a write of a variable that cannot be written
 * then (outputs, locals, constants; a fixed parameter after initialisation, unless it is
 * the value it has), of a non-finite Real, or of a value outside the declared min/max.
 * The variables' rules come from resources/fmu_variables.txt, which the build writes from
 * modelDescription.xml.
 *
 * Refusals made in Python (fmu_runtime/safe_slave.py logs each with status Error): the
 * loader hands pythonfmu its own logger callback, which forwards every message to the
 * host's and remembers the worst status logged during the current call; pythonfmu flushes
 * an instance's messages before each call returns, so a call during which an Error was
 * logged returns fmi2Error (a refused doStep keeps pythonfmu's fmi2Discard). pythonfmu
 * itself always logs (it is instantiated with loggingOn); the loader passes OK-status
 * messages to the host only while the host has logging on.
 */
#include "loader.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum Phase { INSTANTIATED, INITIALIZATION, INITIALIZED, TERMINATED, FAILED };
static const char *const PHASES[] = {"instantiated", "in initialisation mode", "initialised",
                                     "terminated", "in the error state"};
#define TIME_TOLERANCE 1e-9 /* relative: masters compute t_n = n h */
#define NAME_SIZE 128
#define BOUND_SIZE 32

typedef struct {
    int known;
    char type;             /* R I B S */
    char causality[24];    /* as in modelDescription.xml */
    char variability[16];  /* as in modelDescription.xml */
    char min[BOUND_SIZE];  /* "" if none */
    char max[BOUND_SIZE];
    double low, high;      /* -inf / +inf if none */
    double value;          /* a fixed parameter's value: start, then each accepted write */
    double start;
    char name[NAME_SIZE];
} Variable;

typedef struct {
    fmi2Component inner;
    const Wrapper *w;
    fmi2CallbackFunctions host, relay;
    char name[NAME_SIZE];
    int phase, logging;
    double time; /* s: the start time, then the end of the last step */
    fmi2Status logged; /* the worst status pythonfmu logged during the current call */
    Variable *vars;    /* indexed by value reference */
    size_t count;
} Instance;

typedef struct {
    unsigned magic;
    int phase;
    double time;
    fmi2FMUstate inner;
} Saved;
#define SAVED_MAGIC 0x4155564cu /* "AUVL" */
#define SAVED_HEADER (sizeof(unsigned) + sizeof(int) + sizeof(double))

/* ---- logging ------------------------------------------------------------------------ */

static void emit(const fmi2CallbackFunctions *host, const char *instance, fmi2Status status,
                 const char *text)
{
    char escaped[2048]; /* hosts treat the message as a printf format */
    size_t j = 0;
    for (size_t i = 0; text[i] && j + 2 < sizeof escaped; i++) {
        if (text[i] == '%') escaped[j++] = '%';
        escaped[j++] = text[i];
    }
    escaped[j] = '\0';
    if (host && host->logger) {
        host->logger(host->componentEnvironment, instance, status,
                     status >= fmi2Error ? "logStatusError" : "logAll", escaped);
    } else {
        fprintf(stderr, "%s: %s\n", instance ? instance : "FMU", text);
    }
}

static fmi2Status refuse(Instance *c, const char *format, ...)
{
    char text[1536];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    emit(&c->host, c->name, fmi2Error, text);
    return fmi2Error;
}

static void relay(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                  fmi2String category, fmi2String message, ...)
{
    Instance *c = (Instance *)env;
    if (status > c->logged) c->logged = status;
    if (c->host.logger && (c->logging || status >= fmi2Warning)) {
        c->host.logger(c->host.componentEnvironment, instance, status, category, message);
    }
}

/* What pythonfmu answered, raised to fmi2Error if Python logged an Error meanwhile. */
static fmi2Status answer(Instance *c, fmi2Status status)
{
    if (status == fmi2Fatal || c->logged == fmi2Fatal) {
        c->phase = FAILED;
        return fmi2Fatal;
    }
    return status < fmi2Discard && c->logged >= fmi2Error ? fmi2Error : status;
}

/* Shortest text that reads back as the same double, like Python's repr. */
static const char *show(double x, char *out)
{
    if (isnan(x)) return strcpy(out, "nan");
    if (isinf(x)) return strcpy(out, x > 0 ? "inf" : "-inf");
    for (int digits = 15; digits <= 17; digits++) {
        snprintf(out, 32, "%.*g", digits, x);
        if (strtod(out, NULL) == x) break;
    }
    if (!strpbrk(out, ".e")) strcat(out, ".0");
    return out;
}

/* ---- the variables' rules ----------------------------------------------------------- */

static double bound(const char *text, double none)
{
    return text[0] ? strtod(text, NULL) : none;
}

/* Lines "vr type causality variability min max start name" ("-" for none). */
static int read_variables(Instance *c, const char *resources)
{
    char path[4200], line[512];
    snprintf(path, sizeof path, "%s/fmu_variables.txt", resources);
    FILE *in = fopen(path, "r");
    if (!in) return 0;
    while (fgets(line, sizeof line, in)) {
        unsigned vr;
        char type, causality[24], variability[16], min[BOUND_SIZE], max[BOUND_SIZE],
            start[BOUND_SIZE], name[NAME_SIZE];
        if (sscanf(line, "%u %c %23s %15s %31s %31s %31s %127s", &vr, &type, causality,
                   variability, min, max, start, name) != 8 || vr > 100000) {
            continue;
        }
        if (vr >= c->count) {
            Variable *grown = realloc(c->vars, (vr + 1) * sizeof *grown);
            if (!grown) break;
            memset(grown + c->count, 0, (vr + 1 - c->count) * sizeof *grown);
            c->vars = grown;
            c->count = vr + 1;
        }
        Variable *v = &c->vars[vr];
        v->known = 1;
        v->type = type;
        snprintf(v->causality, sizeof v->causality, "%s", causality);
        snprintf(v->variability, sizeof v->variability, "%s", variability);
        snprintf(v->min, sizeof v->min, "%s", strcmp(min, "-") ? min : "");
        snprintf(v->max, sizeof v->max, "%s", strcmp(max, "-") ? max : "");
        v->low = bound(v->min, -INFINITY);
        v->high = bound(v->max, INFINITY);
        v->start = v->value = strcmp(start, "-") ? strtod(start, NULL) : NAN;
        snprintf(v->name, sizeof v->name, "%s", name);
    }
    fclose(in);
    return 1;
}

static const char *TYPE_NAMES(char type)
{
    return type == 'R' ? "Real" : type == 'I' ? "Integer" : type == 'B' ? "Boolean" : "String";
}

static void show_value(char type, double x, char *out)
{
    if (type == 'I') snprintf(out, 40, "%d", (int)x);
    else if (type == 'B') strcpy(out, x != 0 ? "True" : "False");
    else if (type == 'S') strcpy(out, "the string");
    else show(x, out);
}

/* Why writing ``x`` (a String's is NAN) to ``vr`` now is refused, or NULL. The value is
 * formatted only for a refusal: formatting costs more than every check together. */
static const char *write_refusal(const Instance *c, fmi2ValueReference vr, char type, double x,
                                 char *why, size_t n)
{
    const Variable *v = vr < c->count && c->vars[vr].known ? &c->vars[vr] : NULL;
    if (!v) {
        snprintf(why, n, "set%s of valueReference %u refused: no such variable",
                 TYPE_NAMES(type), vr);
        return why;
    }
    const char *problem = NULL;
    if (v->type != type) {
        snprintf(why, n, "%s is a %s, not a %s", v->name, TYPE_NAMES(v->type), TYPE_NAMES(type));
        return why;
    } else if (type == 'R' && !isfinite(x)) {
        problem = "expected a finite number";
    } else if (x < v->low || x > v->high) {
        problem = "range";
    } else if (v->variability[0] == 'c' && !strcmp(v->variability, "constant")) {
        problem = "a constant cannot be set";
    } else if (!strcmp(v->causality, "input") ||
               (!strcmp(v->causality, "parameter") && strcmp(v->variability, "fixed"))) {
        return NULL;
    } else if (!strcmp(v->causality, "parameter")) {
        if (c->phase <= INITIALIZATION || (type != 'S' && x == v->value)) return NULL;
        problem = "a fixed parameter can only be set before initialisation";
    }
    char shown[40];
    show_value(type, x, shown);
    if (!problem) {
        snprintf(why, n, "%s = %s refused: a %s cannot be set", v->name, shown, v->causality);
    } else if (!strcmp(problem, "range")) {
        snprintf(why, n, "%s = %s refused: expected %s%s%s%s%s", v->name, shown, v->min,
                 v->min[0] ? " <= " : "", v->name, v->max[0] ? " <= " : "", v->max);
    } else {
        snprintf(why, n, "%s = %s refused: %s", v->name, shown, problem);
    }
    return why;
}

/* Check every value first: a refused call writes nothing. */
static fmi2Status check_writes(Instance *c, const fmi2ValueReference vr[], size_t n, char type,
                               const double *values)
{
    char why[512];
    if (c->phase >= TERMINATED) {
        return refuse(c, "fmi2Set%s refused: the FMU is %s", TYPE_NAMES(type), PHASES[c->phase]);
    }
    for (size_t i = 0; i < n; i++) {
        if (write_refusal(c, vr[i], type, values ? values[i] : NAN, why, sizeof why)) {
            return refuse(c, "%s", why);
        }
    }
    return fmi2OK;
}

static void remember_writes(Instance *c, const fmi2ValueReference vr[], size_t n,
                            const double *values)
{
    for (size_t i = 0; i < n; i++) c->vars[vr[i]].value = values[i];
}

static void reset_values(Instance *c)
{
    for (size_t i = 0; i < c->count; i++) c->vars[i].value = c->vars[i].start;
}

/* ---- instantiate / free ------------------------------------------------------------- */

/* A file:// URI (or a plain path) as a path, %XX decoded. */
static void uri_to_path(const char *uri, char *out, size_t n)
{
    const char *p = uri ? uri : "";
    if (!strncmp(p, "file://", 7)) p += 7;
    else if (!strncmp(p, "file:", 5)) p += 5;
#ifdef _WIN32
    if (p[0] == '/' && p[1] && p[2] == ':') p++; /* file:///C:/... */
#endif
    size_t j = 0;
    for (; *p && j + 1 < n; p++) {
        unsigned code;
        if (p[0] == '%' && p[1] && p[2] && sscanf(p + 1, "%2x", &code) == 1) {
            out[j++] = (char)code;
            p += 2;
        } else {
            out[j++] = *p;
        }
    }
    out[j] = '\0';
    while (j > 1 && (out[j - 1] == '/' || out[j - 1] == '\\')) out[--j] = '\0';
}

FMI2_EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                                          fmi2String resources,
                                          const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean loggingOn)
{
    char path[4096], why[3072];
    uri_to_path(resources, path, sizeof path);
    const Wrapper *w = loader_runtime(path, why, sizeof why);
    if (!w) {
        char line[3200];
        snprintf(line, sizeof line, "the FMU's loader cannot start Python: %s", why);
        emit(functions, name, fmi2Error, line);
        return NULL;
    }
    Instance *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    if (functions) c->host = *functions;
    c->relay = c->host;
    c->relay.logger = relay;
    c->relay.componentEnvironment = c;
    c->logging = loggingOn;
    snprintf(c->name, sizeof c->name, "%s", name ? name : "");
    if (type != fmi2CoSimulation || !read_variables(c, path)) {
        refuse(c, type != fmi2CoSimulation
                      ? "fmi2Instantiate refused: the FMU supports co-simulation only"
                      : "fmi2Instantiate refused: resources/fmu_variables.txt is missing");
    } else {
        c->w = w;
        c->inner = w->instantiate(name, type, guid, resources, &c->relay, visible, fmi2True);
    }
    if (!c->inner) {
        free(c->vars);
        free(c);
        return NULL;
    }
    return c;
}

FMI2_EXPORT void fmi2FreeInstance(fmi2Component component)
{
    Instance *c = (Instance *)component;
    if (!c) return;
    c->w->freeInstance(c->inner);
    free(c->vars);
    free(c);
}

FMI2_EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
FMI2_EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

FMI2_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn,
                                           size_t n, const fmi2String categories[])
{
    (void)n, (void)categories; /* pythonfmu stays logging: the loader needs its Errors */
    if (!component) return fmi2Error;
    ((Instance *)component)->logging = loggingOn;
    return fmi2OK;
}

/* ---- the call sequence -------------------------------------------------------------- */

#define INSTANCE(component)                    \
    Instance *c = (Instance *)(component);     \
    if (!c) return fmi2Error;                  \
    c->logged = fmi2OK

FMI2_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component component, fmi2Boolean hasTolerance,
                                           fmi2Real tolerance, fmi2Real startTime,
                                           fmi2Boolean hasStop, fmi2Real stopTime)
{
    INSTANCE(component);
    char shown[40];
    if (c->phase != INSTANTIATED) {
        return refuse(c,
                      "setupExperiment refused: the FMU is %s (FMI 2.0 allows it only between "
                      "instantiation and initialisation)",
                      PHASES[c->phase]);
    }
    if (!isfinite(startTime)) {
        return refuse(c, "setupExperiment refused: startTime = %s s, expected a finite number",
                      show(startTime, shown));
    }
    fmi2Status s = answer(c, c->w->setupExperiment(c->inner, hasTolerance, tolerance, startTime,
                                                   hasStop, stopTime));
    if (s == fmi2OK) c->time = startTime;
    return s;
}

FMI2_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component component)
{
    INSTANCE(component);
    if (c->phase != INSTANTIATED) {
        return refuse(c,
                      "enterInitializationMode refused: the FMU is %s (FMI 2.0 allows it once, "
                      "right after instantiation)",
                      PHASES[c->phase]);
    }
    fmi2Status s = answer(c, c->w->enterInitializationMode(c->inner));
    if (s == fmi2OK) c->phase = INITIALIZATION;
    return s;
}

FMI2_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component component)
{
    INSTANCE(component);
    if (c->phase != INITIALIZATION) {
        return refuse(c,
                      "exitInitializationMode refused: the FMU is %s, not in initialisation "
                      "mode (call enterInitializationMode first)",
                      PHASES[c->phase]);
    }
    fmi2Status s = answer(c, c->w->exitInitializationMode(c->inner));
    c->phase = s <= fmi2Warning ? INITIALIZED : FAILED;
    return s;
}

FMI2_EXPORT fmi2Status fmi2DoStep(fmi2Component component, fmi2Real t, fmi2Real h,
                                  fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    INSTANCE(component);
    char at[40], shown[40], now[40];
    if (c->phase != INITIALIZED) {
        show(t, at);
        return refuse(c, "doStep at t = %s s refused: the FMU is %s%s", at, PHASES[c->phase],
                      c->phase < INITIALIZED ? " (call exitInitializationMode first)" : "");
    }
    if (!(isfinite(h) && h > 0.0)) {
        show(t, at);
        return refuse(c,
                      "doStep at t = %s s refused: communication step %s s: expected a finite "
                      "number > 0",
                      at, show(h, shown));
    }
    if (!(isfinite(t) && fabs(t - c->time) <= TIME_TOLERANCE * fmax(1.0, fabs(c->time)))) {
        show(t, at);
        return refuse(c,
                      "doStep at t = %s s refused: currentCommunicationPoint = %s s is not the "
                      "FMU's current time %s s (the start time or the end of the last step)",
                      at, at, show(c->time, now));
    }
    fmi2Status s = answer(c, c->w->doStep(c->inner, t, h, noSetFMUStatePriorToCurrentPoint));
    if (s <= fmi2Warning) c->time = t + h;
    return s;
}

FMI2_EXPORT fmi2Status fmi2Terminate(fmi2Component component)
{
    INSTANCE(component);
    fmi2Status s = answer(c, c->w->terminate(c->inner));
    if (c->phase != FAILED) c->phase = TERMINATED;
    return s;
}

FMI2_EXPORT fmi2Status fmi2Reset(fmi2Component component)
{
    INSTANCE(component);
    fmi2Status s = answer(c, c->w->reset(c->inner));
    if (s <= fmi2Warning) {
        c->phase = INSTANTIATED;
        c->time = 0.0;
        reset_values(c);
    }
    return s;
}

/* ---- values ------------------------------------------------------------------------- */

#define FORWARD(function, ...) \
    (c->w->function ? answer(c, c->w->function(c->inner, __VA_ARGS__)) : fmi2Error)

FMI2_EXPORT fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[],
                                   size_t n, fmi2Real values[])
{
    INSTANCE(component);
    return FORWARD(getReal, vr, n, values);
}

FMI2_EXPORT fmi2Status fmi2GetInteger(fmi2Component component, const fmi2ValueReference vr[],
                                      size_t n, fmi2Integer values[])
{
    INSTANCE(component);
    return FORWARD(getInteger, vr, n, values);
}

FMI2_EXPORT fmi2Status fmi2GetBoolean(fmi2Component component, const fmi2ValueReference vr[],
                                      size_t n, fmi2Boolean values[])
{
    INSTANCE(component);
    return FORWARD(getBoolean, vr, n, values);
}

FMI2_EXPORT fmi2Status fmi2GetString(fmi2Component component, const fmi2ValueReference vr[],
                                     size_t n, fmi2String values[])
{
    INSTANCE(component);
    return FORWARD(getString, vr, n, values);
}

FMI2_EXPORT fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[],
                                   size_t n, const fmi2Real values[])
{
    INSTANCE(component);
    if (check_writes(c, vr, n, 'R', values) != fmi2OK) return fmi2Error;
    fmi2Status s = FORWARD(setReal, vr, n, values);
    if (s == fmi2OK) remember_writes(c, vr, n, values);
    return s;
}

/* An Integer's or Boolean's values as doubles for the checks (a small array on the stack
 * for the usual few values). */
#define AS_DOUBLES(values, n, out, buffer)                                   \
    double buffer[16] = {0}, *out = n <= 16 ? buffer : malloc(n * sizeof(double)); \
    if (!out) return fmi2Error;                                              \
    for (size_t i = 0; i < n; i++) out[i] = values[i]

FMI2_EXPORT fmi2Status fmi2SetInteger(fmi2Component component, const fmi2ValueReference vr[],
                                      size_t n, const fmi2Integer values[])
{
    INSTANCE(component);
    AS_DOUBLES(values, n, x, buffer);
    fmi2Status s = check_writes(c, vr, n, 'I', x);
    if (s == fmi2OK) s = FORWARD(setInteger, vr, n, values);
    if (s == fmi2OK) remember_writes(c, vr, n, x);
    if (x != buffer) free(x);
    return s;
}

FMI2_EXPORT fmi2Status fmi2SetBoolean(fmi2Component component, const fmi2ValueReference vr[],
                                      size_t n, const fmi2Boolean values[])
{
    INSTANCE(component);
    AS_DOUBLES(values, n, x, buffer);
    for (size_t i = 0; i < n; i++) x[i] = x[i] != 0;
    fmi2Status s = check_writes(c, vr, n, 'B', x);
    if (s == fmi2OK) s = FORWARD(setBoolean, vr, n, values);
    if (s == fmi2OK) remember_writes(c, vr, n, x);
    if (x != buffer) free(x);
    return s;
}

FMI2_EXPORT fmi2Status fmi2SetString(fmi2Component component, const fmi2ValueReference vr[],
                                     size_t n, const fmi2String values[])
{
    INSTANCE(component);
    if (check_writes(c, vr, n, 'S', NULL) != fmi2OK) return fmi2Error;
    return FORWARD(setString, vr, n, values);
}

/* ---- FMU state: pythonfmu's, with the loader's phase and time ---------------------- */

FMI2_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component component, fmi2FMUstate *state)
{
    INSTANCE(component);
    Saved *saved = state && *state ? (Saved *)*state : calloc(1, sizeof *saved);
    if (!state || !saved || (*state && saved->magic != SAVED_MAGIC)) {
        return refuse(c, "fmi2GetFMUstate refused: not an FMU state of this FMU");
    }
    fmi2Status s = FORWARD(getFMUstate, &saved->inner);
    if (s > fmi2Warning) {
        if (!*state) free(saved);
        return s;
    }
    saved->magic = SAVED_MAGIC;
    saved->phase = c->phase;
    saved->time = c->time;
    *state = saved;
    return s;
}

FMI2_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component component, fmi2FMUstate state)
{
    INSTANCE(component);
    Saved *saved = (Saved *)state;
    if (!saved || saved->magic != SAVED_MAGIC) {
        return refuse(c, "fmi2SetFMUstate refused: not an FMU state of this FMU");
    }
    fmi2Status s = FORWARD(setFMUstate, saved->inner);
    if (s <= fmi2Warning) {
        c->phase = saved->phase;
        c->time = saved->time;
    }
    return s;
}

FMI2_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component component, fmi2FMUstate *state)
{
    INSTANCE(component);
    if (!state || !*state) return fmi2OK;
    Saved *saved = (Saved *)*state;
    fmi2Status s = FORWARD(freeFMUstate, &saved->inner);
    free(saved);
    *state = NULL;
    return s;
}

FMI2_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component component, fmi2FMUstate state,
                                                  size_t *size)
{
    INSTANCE(component);
    Saved *saved = (Saved *)state;
    if (!saved || saved->magic != SAVED_MAGIC) return refuse(c, "not an FMU state of this FMU");
    fmi2Status s = FORWARD(serializedFMUstateSize, saved->inner, size);
    if (s <= fmi2Warning) *size += SAVED_HEADER;
    return s;
}

FMI2_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component component, fmi2FMUstate state,
                                             fmi2Byte bytes[], size_t size)
{
    INSTANCE(component);
    Saved *saved = (Saved *)state;
    if (!saved || saved->magic != SAVED_MAGIC || size < SAVED_HEADER) {
        return refuse(c, "fmi2SerializeFMUstate refused: not an FMU state of this FMU");
    }
    memcpy(bytes, &saved->magic, sizeof(unsigned));
    memcpy(bytes + sizeof(unsigned), &saved->phase, sizeof(int));
    memcpy(bytes + sizeof(unsigned) + sizeof(int), &saved->time, sizeof(double));
    return FORWARD(serializeFMUstate, saved->inner, bytes + SAVED_HEADER, size - SAVED_HEADER);
}

FMI2_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component component, const fmi2Byte bytes[],
                                               size_t size, fmi2FMUstate *state)
{
    INSTANCE(component);
    unsigned magic = 0;
    if (size >= SAVED_HEADER) memcpy(&magic, bytes, sizeof magic);
    Saved *saved = magic == SAVED_MAGIC ? calloc(1, sizeof *saved) : NULL;
    if (!saved) return refuse(c, "fmi2DeSerializeFMUstate refused: not a state of this FMU");
    saved->magic = magic;
    memcpy(&saved->phase, bytes + sizeof(unsigned), sizeof(int));
    memcpy(&saved->time, bytes + sizeof(unsigned) + sizeof(int), sizeof(double));
    fmi2Status s =
        FORWARD(deSerializeFMUstate, bytes + SAVED_HEADER, size - SAVED_HEADER, &saved->inner);
    if (s > fmi2Warning || saved->phase < INSTANTIATED || saved->phase > FAILED) {
        free(saved);
        return s > fmi2Warning ? s : refuse(c, "fmi2DeSerializeFMUstate refused: bad phase");
    }
    *state = saved;
    return s;
}

/* ---- the rest, forwarded ------------------------------------------------------------ */

FMI2_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component component,
                                                    const fmi2ValueReference u[], size_t nu,
                                                    const fmi2ValueReference z[], size_t nz,
                                                    const fmi2Real dv[], fmi2Real dz[])
{
    INSTANCE(component);
    return FORWARD(getDirectionalDerivative, u, nu, z, nz, dv, dz);
}

FMI2_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component component,
                                                   const fmi2ValueReference vr[], size_t n,
                                                   const fmi2Integer order[],
                                                   const fmi2Real values[])
{
    INSTANCE(component);
    return FORWARD(setRealInputDerivatives, vr, n, order, values);
}

FMI2_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component component,
                                                    const fmi2ValueReference vr[], size_t n,
                                                    const fmi2Integer order[], fmi2Real values[])
{
    INSTANCE(component);
    return FORWARD(getRealOutputDerivatives, vr, n, order, values);
}

FMI2_EXPORT fmi2Status fmi2CancelStep(fmi2Component component)
{
    INSTANCE(component);
    return c->w->cancelStep ? answer(c, c->w->cancelStep(c->inner)) : fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2GetStatus(fmi2Component component, const fmi2StatusKind kind,
                                     fmi2Status *value)
{
    INSTANCE(component);
    return FORWARD(getStatus, kind, value);
}

FMI2_EXPORT fmi2Status fmi2GetRealStatus(fmi2Component component, const fmi2StatusKind kind,
                                         fmi2Real *value)
{
    INSTANCE(component);
    return FORWARD(getRealStatus, kind, value);
}

FMI2_EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component component, const fmi2StatusKind kind,
                                            fmi2Integer *value)
{
    INSTANCE(component);
    return FORWARD(getIntegerStatus, kind, value);
}

FMI2_EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component component, const fmi2StatusKind kind,
                                            fmi2Boolean *value)
{
    INSTANCE(component);
    return FORWARD(getBooleanStatus, kind, value);
}

FMI2_EXPORT fmi2Status fmi2GetStringStatus(fmi2Component component, const fmi2StatusKind kind,
                                           fmi2String *value)
{
    INSTANCE(component);
    return FORWARD(getStringStatus, kind, value);
}
