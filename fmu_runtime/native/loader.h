/* The FMU's native runtime: declarations shared by its C files.
 *
 * loader.c   the exported FMI 2.0 co-simulation functions: the standard's call sequence,
 *            the variables' rules, the status functions; each call then goes to a backend
 * values.c   the variables' values in C: fmi2Get/fmi2Set answered from the value buffers
 *            the slave shares with the runtime, without Python
 * runtime.c  finds a Python for the process (the candidates, in order) and starts it
 * probe.c    asks one candidate Python, in a subprocess, what it is
 * python.c   the CPython C API, every function resolved with dlsym from the libpython in
 *            the process (no link-time dependency: one binary for every CPython >= 3.9)
 * slave.c    the default backend: constructs the Python slave class and calls it directly
 * forward.c  the fallback backend (AUV_FMU_RUNTIME=pythonfmu): pythonfmu's own binary
 *
 * The FMI 2.0 types are declared here rather than taken from the standard's headers so
 * that the runtime compiles from this folder alone; they are the ABI of
 * fmi2TypesPlatform.h and fmi2FunctionTypes.h (FMI 2.0.x, "default" platform).
 */
#ifndef AUV_FMU_LOADER_H
#define AUV_FMU_LOADER_H

#include "glibc_floor.h"
#include "platform.h"

#include <stddef.h>

#ifdef _WIN32
#define FMI2_EXPORT __declspec(dllexport) /* then nothing else is exported */
#else
#define FMI2_EXPORT __attribute__((visibility("default")))
#endif

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum {
    fmi2DoStepStatus,
    fmi2PendingStatus,
    fmi2LastSuccessfulTime,
    fmi2Terminated
} fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String,
                                   fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);

typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2StepFinished stepFinished;
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

#define fmi2True 1
#define fmi2False 0

#define PATH_SIZE 4096
#define NAME_SIZE 128
#define BOUND_SIZE 32
#define LINE_SIZE 2048 /* one log line */

/* The environment variables a user sets (docs/native-loader.md). */
#define PYTHON_VARIABLE "AUV_FMU_PYTHON"   /* a Python executable or a venv's folder */
#define RUNTIME_VARIABLE "AUV_FMU_RUNTIME" /* "pythonfmu": pythonfmu's own binary */
#define RECORD_FILE "fmu_runtime.txt"      /* in resources/, written by the build */
#define VARIABLES_FILE "fmu_variables.txt" /* in resources/, written by the build */

/* resources/fmu_runtime.txt: what the build knows that the runtime needs. */
typedef struct {
    char guid[64];
    char package[64];      /* the build's top-level package, auvfmu_<hash> */
    char module[256];      /* the slave class's module, inside that package */
    char slave_class[128]; /* the slave class's name */
    char build_python[PATH_SIZE]; /* the Python the FMU was built with */
    int interpolates_inputs;      /* canInterpolateInputs: the slave takes input derivatives */
    char log_categories[512];     /* LogCategories, comma-separated */
} Record;

typedef struct {
    int known;
    char type;            /* R I B S */
    int slot;             /* its index among the variables of its type, in vr order */
    char causality[24];   /* as in modelDescription.xml */
    char variability[16]; /* as in modelDescription.xml */
    char min[BOUND_SIZE]; /* "" if none */
    char max[BOUND_SIZE];
    double low, high; /* -inf / +inf if none */
    double value;     /* a fixed parameter's value: start, then each accepted write */
    double start;
    int refused;          /* an input's or tunable parameter's value refused for itself ... */
    double refused_value; /* ... this one, stands: each doStep is discarded (loader.c) */
    char name[NAME_SIZE];
} Variable;

/* The FMI 2.0 co-simulation phases an instance goes through (loader.c). */
enum Phase { INSTANTIATED, INITIALIZATION, INITIALIZED, TERMINATED, FAILED };

/* The value buffers (fmu_runtime/value_buffers.py is the other side): one per type, in
 * slot order, laid out by the slave; flags per value reference; a control block; the
 * input derivatives. The memory is the slave's (Python bytearrays the runtime holds
 * buffer exports of, so it can neither move nor go while the runtime holds it); Strings
 * are the runtime's own copies. All NULL with the fallback backend. */
#define FLAG_WATCHED 1 /* the value lives in the slave's own storage: it takes writes */
#define FLAG_CHANGED 2 /* a watched variable written since the slave took its writes */
#define FLAG_WRITTEN 4 /* written (accepted) since instantiation */
#define FLAG_DERIVATIVE_1 8
#define FLAG_DERIVATIVE_2 16
#define CONTROL_CHANGES 0     /* some watched variable is CHANGED */
#define CONTROL_STALE 1       /* written since the outputs to start from were computed */
#define CONTROL_DERIVATIVES 2 /* some input derivative is set */
#define CONTROL_SIZE 8

typedef struct {
    double *reals;
    int *integers;
    int *booleans;
    unsigned char *flags;   /* per value reference */
    unsigned char *control; /* CONTROL_SIZE bytes */
    double *derivatives;    /* order 1 then order 2, per Real slot */
    char **strings;         /* the runtime's copies, per String slot (NULL: not known yet) */
    unsigned char *dirty;   /* per String slot: written since the slave took it */
    int strings_dirty;
    size_t reals_n, integers_n, booleans_n, strings_n;
} Values;

typedef struct Backend Backend;

typedef struct {
    const Backend *backend;
    void *slave; /* the backend's own instance (a PyObject *, or pythonfmu's component) */
    void *extra; /* the backend's per-instance data */
    fmi2CallbackFunctions host;
    char *name; /* the host's instanceName, whole: every log message names it */
    char resources[PATH_SIZE]; /* a path, decoded from the host's URI */
    Record record;
    int phase, logging, visible;
    unsigned long long debugged; /* bit i: debug messages of LogCategories[i] pass */
    double time;       /* s: the start time, then the end of the last step */
    double stop;       /* s: setupExperiment's stopTime, INFINITY when it defines none */
    unsigned long writes;   /* values set (fmi2Set*, derivatives, states): counts changes */
    int discarded;          /* the last doStep was answered fmi2Discard ... */
    double discarded_at[2]; /* ... from this t, with this h (s) ... */
    unsigned long discarded_writes; /* ... when ``writes`` was this */
    size_t refusals;   /* variables whose refused value stands (Variable.refused) */
    fmi2Status logged; /* the worst status logged during the current call */
    Variable *vars;    /* indexed by value reference */
    size_t count;
    Values values;
    void *states; /* the FMU states it took that are alive: freed with it (loader.c) */
} Instance;

/* What the FMI functions need from whatever runs the slave. Each returns the status the
 * backend answers; what it logs meanwhile goes through instance_log. */
struct Backend {
    int (*start)(Instance *); /* makes c->slave; 0 (with a line logged) on failure */
    void (*stop)(Instance *);
    fmi2Status (*setup)(Instance *, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
    fmi2Status (*enter)(Instance *);
    fmi2Status (*exit)(Instance *);
    fmi2Status (*step)(Instance *, fmi2Real, fmi2Real, fmi2Boolean);
    fmi2Status (*terminate)(Instance *);
    fmi2Status (*reset)(Instance *);
    /* values: double[] for 'R', int[] for 'I' and 'B', fmi2String[] for 'S' */
    fmi2Status (*get)(Instance *, char type, const fmi2ValueReference *, size_t, void *);
    fmi2Status (*set)(Instance *, char type, const fmi2ValueReference *, size_t, const void *);
    fmi2Status (*save)(Instance *, void **state);
    fmi2Status (*restore)(Instance *, void *state);
    void (*discard)(Instance *, void *state);
    /* the state's bytes: their number in *size, and copied to out when capacity allows */
    fmi2Status (*state_bytes)(Instance *, void *state, fmi2Byte *out, size_t capacity,
                              size_t *size);
    fmi2Status (*state_from_bytes)(Instance *, const fmi2Byte *, size_t, void **state);
    fmi2Status (*derivatives)(Instance *, const fmi2ValueReference *, size_t,
                              const fmi2Integer *, const fmi2Real *);
    /* tell the slave the categories whose debug messages pass (debug_categories) */
    fmi2Status (*debug)(Instance *);
};

extern const Backend python_backend;    /* slave.c */
extern const Backend pythonfmu_backend; /* forward.c */

/* loader.c: one message to the host's logger (``message`` is passed as the printf format,
 * so a literal % must come doubled), remembered as the call's worst status. */
void instance_log(Instance *c, fmi2Status status, const char *category, const char *message);
/* loader.c: the categories whose debug (fmi2OK) messages reach the host, comma-separated
 * into ``out`` ("" for none): every declared one with logging on for all, else those
 * fmi2SetDebugLogging named. */
void debug_categories(const Instance *c, char *out, size_t n);
/* loader.c: ``text`` with every % doubled into ``out`` (``size`` bytes, 2 * strlen(text) + 1
 * hold UTF-8 text whole): hosts treat a message as a printf format. Each byte that is no
 * UTF-8 becomes \xNN (4 bytes), so the message is UTF-8 whatever the host handed in. A text
 * cut short (by ``size``) is cut between characters. */
void escape(const char *text, char *out, size_t size);
/* printf-style: one Error line (its % escaped for the host); returns fmi2Error. */
fmi2Status refuse(Instance *c, const char *format, ...)
    __attribute__((format(printf, 2, 3)));

/* loader.c: the shortest text that reads back as the same double, laid out as Python's
 * repr (5e-324, 0.0001, 1000000000000000.0, 1e+16, nan), into ``out`` (32 bytes). */
const char *show(double x, char *out);

/* loader.c: how many of the first ``n`` bytes of UTF-8 ``text`` to keep so that a cut
 * there splits no character. */
size_t whole_characters(const char *text, size_t n);

/* loader.c: the decimal number at ``*text`` (digits only: no sign, no space) into
 * ``*out``, ``*text`` moved past its digits: 1, or 0 when there are no digits or the
 * number is larger than ``most`` (never undefined behaviour, unlike sscanf's %d or %u). */
int read_number(const char **text, unsigned long most, unsigned long *out);

/* loader.c: "major.minor" (``parts`` 2) or "major.minor.micro" (3) at the start of
 * ``text`` into ``numbers``, each from 0 to INT_MAX: 1, or 0 (``numbers`` all 0). With
 * ``whole`` nothing may follow (otherwise anything may: "3.11.7 (main, ...)"). */
int read_version(const char *text, int parts, int whole, int numbers[3]);

/* values.c: the value buffers' part of a call, once loader.c has checked it (known value
 * references of the right type, allowed writes); no Python. A Real read that is not
 * finite is refused with a line naming the variable. */
fmi2Status values_get(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      void *values);
/* A known Real, Integer or Boolean's value as its slot holds it (a Boolean 0 or 1), as is:
 * no check, no Python. */
double values_slot(const Instance *c, fmi2ValueReference vr);
fmi2Status values_set(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      const void *values);
void values_derivatives(Instance *c, const fmi2ValueReference vr[], size_t n,
                        const fmi2Integer order[], const fmi2Real values[]);
/* after each doStep: no input derivative set any more */
void values_clear_derivatives(Instance *c);
/* the buffers' bytes in an FMU state: their number, a copy out, a copy back */
size_t values_bytes(const Values *v, size_t flags_n);
void values_save(const Values *v, size_t flags_n, char *to);
void values_restore(Values *v, size_t flags_n, const char *from);
/* the String copies: one replaced (0 when out of memory), all freed */
int values_keep_string(Values *v, size_t slot, const char *text);
void values_free_strings(Values *v);

/* runtime.c: an initialised CPython >= 3.9 that imports numpy in this process (started
 * once per process if none runs), or 0 after one Error line per candidate passed over. */
int runtime_python(Instance *c);
/* runtime.c: 1 once the Python this copy of the runtime used has shut down (python_gone),
 * read under the lock runtime_python resolves and starts it under: another thread may be
 * doing so, between which CPython is loaded but not yet initialised. */
int runtime_gone(void);

#endif
