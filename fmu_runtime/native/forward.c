/* The fallback backend (AUV_FMU_RUNTIME=pythonfmu): pythonfmu's own binary, shipped
 * unchanged beside this library as <model identifier>_pythonfmu.so (.dll on Windows), with
 * every call forwarded to it once the FMI rules are checked (loader.c) and Python started
 * (runtime.c). pythonfmu's linux64 binary needs glibc 2.32; its win64 one imports
 * python3.dll and the MSVC++ runtime (MSVCP140.dll).
 *
 * It hands pythonfmu a logger of its own, which passes every message to the host's (a
 * NULL category replaced: some hosts crash on one) and feeds the call's worst status.
 *
 * Debug logging: the slave found as below is told the categories whose debug messages
 * pass (its set_debug_logging), as slave.c tells its own; loader.c filters the messages.
 *
 * Input derivatives: pythonfmu's binary answers fmi2SetRealInputDerivatives with "not
 * supported", while our slaves take them (canInterpolateInputs="true" in the same
 * modelDescription.xml for both backends). For a slave that takes them this backend
 * finds, right after pythonfmu's fmi2Instantiate (and again after its fmi2Reset, which
 * constructs another), the slave it constructed
 * (``fmu_runtime.safe_slave.claim_constructed``: the last SafeSlave constructed on this
 * thread, pythonfmu constructing it in the call) and hands each call, once loader.c has
 * checked it, to its ``set_real_input_derivatives`` with the GIL held; the slave's
 * ``do_step`` clears them after the step, as in the default backend. So both backends
 * step with the same inputs and give the same results.
 *
 * pythonfmu 0.7's wrapper releases its interpreter guard twice at process exit (a static
 * destructor, then its ``finalizePythonInterpreter``): right after loading it, its
 * ``finalizePythonInterpreter`` is registered as an exit handler, which runs first (exit
 * handlers run last-registered first) while the guard is alive and leaves nothing for the
 * two later releases (fmu_runtime/exit_guard.py does the same from Python for a wrapper
 * loaded without this runtime). On Windows nothing is registered: not checked there.
 */
#include "loader.h"
#include "python.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    fmi2Component (*instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                 const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
    void (*freeInstance)(fmi2Component);
    fmi2Status (*setupExperiment)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean,
                                  fmi2Real);
    fmi2Status (*enterInitializationMode)(fmi2Component);
    fmi2Status (*exitInitializationMode)(fmi2Component);
    fmi2Status (*terminate)(fmi2Component);
    fmi2Status (*reset)(fmi2Component);
    fmi2Status (*getReal)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
    fmi2Status (*getInteger)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Integer[]);
    fmi2Status (*getBoolean)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Boolean[]);
    fmi2Status (*getString)(fmi2Component, const fmi2ValueReference[], size_t, fmi2String[]);
    fmi2Status (*setReal)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[]);
    fmi2Status (*setInteger)(fmi2Component, const fmi2ValueReference[], size_t,
                             const fmi2Integer[]);
    fmi2Status (*setBoolean)(fmi2Component, const fmi2ValueReference[], size_t,
                             const fmi2Boolean[]);
    fmi2Status (*setString)(fmi2Component, const fmi2ValueReference[], size_t,
                            const fmi2String[]);
    fmi2Status (*getFMUstate)(fmi2Component, fmi2FMUstate *);
    fmi2Status (*setFMUstate)(fmi2Component, fmi2FMUstate);
    fmi2Status (*freeFMUstate)(fmi2Component, fmi2FMUstate *);
    fmi2Status (*serializedFMUstateSize)(fmi2Component, fmi2FMUstate, size_t *);
    fmi2Status (*serializeFMUstate)(fmi2Component, fmi2FMUstate, fmi2Byte[], size_t);
    fmi2Status (*deSerializeFMUstate)(fmi2Component, const fmi2Byte[], size_t, fmi2FMUstate *);
    fmi2Status (*doStep)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
} Wrapper;

typedef struct {
    const char *name;
    void **slot;
} Entry;

static Wrapper wrapper;
static int wrapper_loaded;
static char wrapper_path[PATH_SIZE]; /* its file, as loaded */

#define ENTRY(field, name) {name, (void **)&wrapper.field}

static int resolve(void *library)
{
    const Entry entries[] = {
        ENTRY(instantiate, "fmi2Instantiate"),
        ENTRY(freeInstance, "fmi2FreeInstance"),
        ENTRY(setupExperiment, "fmi2SetupExperiment"),
        ENTRY(enterInitializationMode, "fmi2EnterInitializationMode"),
        ENTRY(exitInitializationMode, "fmi2ExitInitializationMode"),
        ENTRY(terminate, "fmi2Terminate"),
        ENTRY(reset, "fmi2Reset"),
        ENTRY(getReal, "fmi2GetReal"),
        ENTRY(getInteger, "fmi2GetInteger"),
        ENTRY(getBoolean, "fmi2GetBoolean"),
        ENTRY(getString, "fmi2GetString"),
        ENTRY(setReal, "fmi2SetReal"),
        ENTRY(setInteger, "fmi2SetInteger"),
        ENTRY(setBoolean, "fmi2SetBoolean"),
        ENTRY(setString, "fmi2SetString"),
        ENTRY(getFMUstate, "fmi2GetFMUstate"),
        ENTRY(setFMUstate, "fmi2SetFMUstate"),
        ENTRY(freeFMUstate, "fmi2FreeFMUstate"),
        ENTRY(serializedFMUstateSize, "fmi2SerializedFMUstateSize"),
        ENTRY(serializeFMUstate, "fmi2SerializeFMUstate"),
        ENTRY(deSerializeFMUstate, "fmi2DeSerializeFMUstate"),
        ENTRY(doStep, "fmi2DoStep"),
    };
    for (size_t i = 0; i < sizeof entries / sizeof entries[0]; i++) {
        *entries[i].slot = platform_library_symbol(library, entries[i].name);
        if (!*entries[i].slot) return 0;
    }
    return 1;
}

/* pythonfmu's library: this library's own file name with "_pythonfmu" before its
 * suffix (".so", ".dll"). */
static int load_wrapper(Instance *c)
{
    char path[PATH_SIZE];
    if (!own_path(path, sizeof path - 16) || !strstr(path, LIBRARY_SUFFIX)) {
        refuse(c, "fmi2Instantiate: the runtime cannot find its own file");
        return 0;
    }
    char *dot = strrchr(path, '.');
    snprintf(dot, 16, "_pythonfmu%s", LIBRARY_SUFFIX);
    snprintf(wrapper_path, sizeof wrapper_path, "%s", path);
    void *library = platform_open_wrapper(path);
    if (!library) {
        char error[LINE_SIZE / 2];
        platform_library_error(error, sizeof error);
        refuse(c, "fmi2Instantiate: cannot load pythonfmu's library %s (%s)", path, error);
        return 0;
    }
    void (*finalize)(void *) = NULL; /* as python.c reads a function: ISO C has no cast */
    *(void **)&finalize = platform_library_symbol(library, "finalizePythonInterpreter");
    if (finalize) platform_exit_handler(finalize);
    if (!resolve(library)) {
        refuse(c, "fmi2Instantiate: %s is not an FMI 2.0 co-simulation library", path);
        return 0;
    }
    return 1;
}

/* pythonfmu's messages to the host's logger, with a category, feeding the call's status. */
static void relay(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                  fmi2String category, fmi2String message, ...)
{
    (void)instance;
    instance_log((Instance *)env, status, category, message ? message : "");
}

/* The per-instance data: the callbacks pythonfmu keeps a pointer to, and the Python slave
 * it constructed (a new reference; NULL unless the slave takes input derivatives). */
typedef struct {
    fmi2CallbackFunctions callbacks;
    PyObject *slave;
    int said; /* say_binary has run */
} Forwarded;

#define FORWARDED(c) ((Forwarded *)(c)->extra)

/* The slave pythonfmu just constructed, from the slave's package (see the file comment);
 * NULL (Python's error cleared) if none is found. */
static PyObject *claim_slave(Instance *c)
{
    if (!python_alive()) return NULL;
    char name[sizeof c->record.package + 32];
    snprintf(name, sizeof name, "%s.fmu_runtime.safe_slave", c->record.package);
    int gil = py.GILState_Ensure();
    PyObject *module = py.Import_ImportModule(name);
    PyObject *claim = module ? py.GetAttrString(module, "claim_constructed") : NULL;
    PyObject *slave = claim ? py.CallFunctionObjArgs(claim, NULL) : NULL;
    if (slave == py.None) {
        py.DecRef(slave);
        slave = NULL;
    }
    py.Err_Clear();
    if (claim) py.DecRef(claim);
    if (module) py.DecRef(module);
    py.GILState_Release(gil);
    return slave;
}

/* The resource URI pythonfmu's binary can read, into ``out``, or 0 (refused, with a line):
 * its fmi2Instantiate replaces "%20" with a space, strips PYTHONFMU_URI and opens what is
 * left (platform.h), so any other %XX (a non-ASCII or reserved character), a literal "%20"
 * in a folder's name, and on Windows any non-ASCII character, left it a path that does not
 * exist, and it then crashed its host (its findClass returns NULL without a Python error).
 * It gets the path this runtime decoded, unencoded. */
static int pythonfmu_uri(Instance *c, char *out, size_t n)
{
    const char *why = strstr(c->resources, "%20") ? "\"%20\", which it reads as a space" : NULL;
    for (const char *p = c->resources; !why && PYTHONFMU_ASCII_ONLY && *p; p++) {
        if ((unsigned char)*p >= 0x80) why = "a non-ASCII character, which it cannot open";
    }
    if (why) {
        refuse(c, "fmi2Instantiate refused: the resources path %s holds %s: pythonfmu's "
                  "binary (%s=pythonfmu) cannot load this FMU from there; the FMU's own "
                  "runtime can (%s unset)", c->resources, why, RUNTIME_VARIABLE,
               RUNTIME_VARIABLE);
        return 0;
    }
    snprintf(out, n, "%s%s", PYTHONFMU_URI, c->resources);
    return 1;
}

/* An OK line of "logAll" naming the binary that runs the FMU: the calls are answered as on
 * the runtime, so nothing else tells the fallback is in use. Said once, at the first of
 * fmi2SetupExperiment and fmi2EnterInitializationMode, not at fmi2Instantiate: by then
 * the host has set the categories it wants (fmi2SetDebugLogging), and a host asking for
 * others than "logAll" is not shown it. */
static void say_binary(Instance *c)
{
    Forwarded *forwarded = FORWARDED(c);
    if (forwarded->said) return;
    forwarded->said = 1;
    char line[PATH_SIZE + 96], escaped[2 * sizeof line];
    snprintf(line, sizeof line, "the FMU runs on pythonfmu's own binary %s (%s=pythonfmu)",
             wrapper_path, RUNTIME_VARIABLE);
    escape(line, escaped, sizeof escaped);
    instance_log(c, fmi2OK, "logAll", escaped);
}

static int start(Instance *c)
{
    char uri[PATH_SIZE + 16];
    if (!pythonfmu_uri(c, uri, sizeof uri)) return 0;
    platform_lock(LOCK_WRAPPER);
    wrapper_loaded = wrapper_loaded || load_wrapper(c);
    platform_unlock(LOCK_WRAPPER);
    if (!wrapper_loaded) return 0;
    Forwarded *forwarded = calloc(1, sizeof *forwarded);
    if (!forwarded) return 0;
    forwarded->callbacks = c->host;
    forwarded->callbacks.logger = relay;
    forwarded->callbacks.componentEnvironment = c;
    c->extra = forwarded; /* pythonfmu keeps the pointer to the callbacks */
    c->slave = wrapper.instantiate(c->name, fmi2CoSimulation, c->record.guid, uri,
                                   &forwarded->callbacks, c->visible, fmi2True);
    if (!c->slave) {
        free(forwarded);
        c->extra = NULL;
        return 0;
    }
    forwarded->slave = claim_slave(c); /* derivatives, debug */
    return 1;
}

static void stop(Instance *c)
{
    Forwarded *forwarded = FORWARDED(c);
    if (!python_gone()) { /* they would enter Python */
        if (forwarded && forwarded->slave && python_alive()) {
            int gil = py.GILState_Ensure();
            py.DecRef(forwarded->slave);
            py.GILState_Release(gil);
        }
        wrapper.freeInstance(c->slave);
    }
    free(forwarded);
}

/* fmi2SetRealInputDerivatives (checked by loader.c) to the slave's
 * set_real_input_derivatives, which stores them for the next step. */
static fmi2Status derivatives(Instance *c, const fmi2ValueReference vr[], size_t n,
                              const fmi2Integer order[], const fmi2Real values[])
{
    const char *call = "fmi2SetRealInputDerivatives";
    PyObject *slave = FORWARDED(c)->slave;
    if (!slave) return refuse(c, "%s refused: pythonfmu's binary constructed no slave the "
                              "runtime can find", call);
    if (!python_alive()) return refuse(c, "%s refused: Python has shut down", call);
    int gil = py.GILState_Ensure();
    PyObject *lists[3] = {py.List_New((Py_ssize_t)n), py.List_New((Py_ssize_t)n),
                          py.List_New((Py_ssize_t)n)};
    int ok = lists[0] && lists[1] && lists[2];
    for (size_t i = 0; ok && i < n; i++) {
        PyObject *items[3] = {py.Long_FromUnsignedLong(vr[i]), py.Long_FromLong(order[i]),
                              py.Float_FromDouble(values[i])};
        for (int k = 0; k < 3; k++) { /* List_SetItem steals the item, even on failure */
            if (!items[k] || py.List_SetItem(lists[k], (Py_ssize_t)i, items[k]) != 0) ok = 0;
        }
    }
    PyObject *method = ok ? py.GetAttrString(slave, "set_real_input_derivatives") : NULL;
    PyObject *result =
        method ? py.CallFunctionObjArgs(method, lists[0], lists[1], lists[2], NULL) : NULL;
    char error[LINE_SIZE / 2] = "";
    if (!result) python_error(error, sizeof error);
    if (result) py.DecRef(result);
    if (method) py.DecRef(method);
    for (int k = 0; k < 3; k++) {
        if (lists[k]) py.DecRef(lists[k]);
    }
    py.GILState_Release(gil);
    return result ? fmi2OK : refuse(c, "%s: the slave's set_real_input_derivatives raised %s",
                                    call, error);
}

static fmi2Status setup(Instance *c, fmi2Boolean has_tolerance, fmi2Real tolerance,
                        fmi2Real start_time, fmi2Boolean has_stop, fmi2Real stop_time)
{
    say_binary(c);
    return wrapper.setupExperiment(c->slave, has_tolerance, tolerance, start_time, has_stop,
                                   stop_time);
}

static fmi2Status enter(Instance *c)
{
    say_binary(c);
    return wrapper.enterInitializationMode(c->slave);
}
static fmi2Status leave(Instance *c) { return wrapper.exitInitializationMode(c->slave); }
static fmi2Status terminate(Instance *c) { return wrapper.terminate(c->slave); }
/* pythonfmu's fmi2Reset constructs a new slave (on this thread): the input derivatives go
 * to that one from now on, not to the one it replaced. */
static fmi2Status reset(Instance *c)
{
    fmi2Status s = wrapper.reset(c->slave);
    Forwarded *forwarded = FORWARDED(c);
    if (s <= fmi2Warning && python_alive()) {
        PyObject *renewed = claim_slave(c);
        int gil = py.GILState_Ensure();
        if (forwarded->slave) py.DecRef(forwarded->slave);
        py.GILState_Release(gil);
        forwarded->slave = renewed;
    }
    return s;
}

static fmi2Status step(Instance *c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_state)
{
    return wrapper.doStep(c->slave, t, h, no_set_state);
}

static fmi2Status get(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      void *values)
{
    if (type == 'R') return wrapper.getReal(c->slave, vr, n, values);
    if (type == 'I') return wrapper.getInteger(c->slave, vr, n, values);
    if (type == 'B') return wrapper.getBoolean(c->slave, vr, n, values);
    return wrapper.getString(c->slave, vr, n, values);
}

static fmi2Status set(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      const void *values)
{
    if (type == 'R') return wrapper.setReal(c->slave, vr, n, values);
    if (type == 'I') return wrapper.setInteger(c->slave, vr, n, values);
    if (type == 'B') return wrapper.setBoolean(c->slave, vr, n, values);
    return wrapper.setString(c->slave, vr, n, values);
}

static fmi2Status save(Instance *c, void **state)
{
    *state = NULL;
    return wrapper.getFMUstate(c->slave, state);
}

static fmi2Status restore(Instance *c, void *state)
{
    return wrapper.setFMUstate(c->slave, state);
}

static void discard(Instance *c, void *state)
{
    if (state) wrapper.freeFMUstate(c->slave, &state);
}

static fmi2Status state_bytes(Instance *c, void *state, fmi2Byte *out, size_t capacity,
                              size_t *size)
{
    fmi2Status s = wrapper.serializedFMUstateSize(c->slave, state, size);
    if (s > fmi2Warning || !out || capacity < *size) return s;
    return wrapper.serializeFMUstate(c->slave, state, out, *size);
}

static fmi2Status state_from_bytes(Instance *c, const fmi2Byte *bytes, size_t size, void **state)
{
    *state = NULL;
    return wrapper.deSerializeFMUstate(c->slave, bytes, size, state);
}

/* The claimed slave's set_debug_logging (as slave.c's), with the GIL held: pythonfmu's
 * binary passes every message on (instantiated with logging on) and loader.c filters. */
static fmi2Status debug(Instance *c)
{
    PyObject *slave = FORWARDED(c)->slave;
    if (!slave) return fmi2OK; /* none found: its debug messages are of none of its own */
    if (!python_alive()) return refuse(c, "fmi2SetDebugLogging refused: Python has shut down");
    char names[sizeof c->record.log_categories];
    debug_categories(c, names, sizeof names);
    int gil = py.GILState_Ensure();
    PyObject *text = py.Unicode_FromString(names);
    PyObject *method = text ? py.GetAttrString(slave, "set_debug_logging") : NULL;
    PyObject *result = method ? py.CallFunctionObjArgs(method, text, NULL) : NULL;
    char error[LINE_SIZE / 2] = "";
    if (!result) python_error(error, sizeof error);
    PyObject *objects[] = {result, method, text};
    for (size_t i = 0; i < 3; i++) {
        if (objects[i]) py.DecRef(objects[i]);
    }
    py.GILState_Release(gil);
    if (!result) {
        return refuse(c, "fmi2SetDebugLogging: the slave's set_debug_logging raised %s", error);
    }
    return fmi2OK;
}

const Backend pythonfmu_backend = {
    start, stop,    setup,   enter,       leave,            step, terminate, reset, get, set,
    save,  restore, discard, state_bytes, state_from_bytes, derivatives, debug,
};
