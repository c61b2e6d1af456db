/* The default backend: the FMU's Python slave class, constructed and called directly
 * through the CPython C API (no pythonfmu binary involved).
 *
 * Written by hand because pythonfmu's wrapper, the library that does this job in
 * pythonfmu, cannot be rebuilt for old glibc and crashes on NULL arguments, on exceptions
 * and at process exit. What it does with the slave is kept: the same constructor keywords
 * (instance_name, resources, visible), the same methods (setup_experiment, do_step,
 * get_real, ..., _get_fmu_state, _fmu_state_to_bytes), and the slave's log queue passed
 * to the host's logger after each call.
 *
 * The slave's package is imported from the FMU's own resources folder under the build's
 * unique name (resources/fmu_runtime.txt), without touching sys.path: two builds in one
 * process never share a module, two extractions of one build share the same code.
 *
 * Python may have shut down under an instance (a Python host that exits without freeing
 * it): every call checks before taking the GIL, and then frees only C memory.
 */
#define _GNU_SOURCE /* strdup */
#include "loader.h"
#include "python.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    PyObject *cls;   /* the slave class */
    PyObject *queue; /* the slave's log queue (a list of pythonfmu LogMsg) */
    char **strings;  /* what the last fmi2GetString returned, owned here */
    size_t n_strings;
} Extra;

#define EXTRA(c) ((Extra *)(c)->extra)

/* ---- calling Python ----------------------------------------------------------------- */

/* Take the GIL, or refuse when Python is gone or going; the returned token ends the call. */
static int enter(Instance *c, const char *call, int *gil)
{
    if (!python_alive() || !c->slave) {
        refuse(c, "%s refused: Python has shut down in this process", call);
        return 0;
    }
    *gil = py.GILState_Ensure();
    return 1;
}

static void release(PyObject *object)
{
    if (object) py.DecRef(object);
}

/* The slave's log messages (status, category, text) to the host, the queue emptied. */
static void flush_log(Instance *c)
{
    PyObject *queue = EXTRA(c)->queue;
    Py_ssize_t n = queue ? py.List_Size(queue) : 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *item = py.List_GetItem(queue, i); /* borrowed */
        PyObject *status = py.GetAttrString(item, "status");
        PyObject *category = py.GetAttrString(item, "category");
        PyObject *text = py.GetAttrString(item, "msg");
        long level = status ? py.Long_AsLong(status) : fmi2Error;
        const char *kind = category && category != py.None ? py.Unicode_AsUTF8(category) : NULL;
        const char *message = text ? py.Unicode_AsUTF8(text) : NULL;
        if (level < fmi2OK || level > fmi2Fatal) level = fmi2Error;
        instance_log(c, (fmi2Status)level, kind, message ? message : "(unreadable message)");
        py.Err_Clear();
        release(status);
        release(category);
        release(text);
    }
    if (n > 0) py.List_SetSlice(queue, 0, n, NULL);
    py.Err_Clear();
}

static void leave(Instance *c, int gil)
{
    flush_log(c);
    py.GILState_Release(gil);
}

/* ``target.method(*args)`` (args stolen); NULL with an Error line naming the exception. */
static PyObject *invoke(Instance *c, PyObject *target, const char *method, PyObject *args,
                        const char *call)
{
    PyObject *function = target && args ? py.GetAttrString(target, method) : NULL;
    PyObject *result = function ? py.Call(function, args, NULL) : NULL;
    if (!result) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "%s: the slave's %s raised %s", call, method, error);
    }
    release(function);
    release(args);
    return result;
}

/* A tuple of ``n`` new references (stolen); NULL if one is NULL. */
static PyObject *pack(int n, PyObject *items[])
{
    PyObject *tuple = py.Tuple_New(n);
    for (int i = 0; i < n; i++) {
        if (!tuple || !items[i]) {
            for (int j = i; j < n; j++) release(items[j]);
            release(tuple);
            return NULL;
        }
        py.Tuple_SetItem(tuple, i, items[i]);
    }
    return tuple;
}

/* A method without arguments: fmi2OK, or fmi2Error when it raised. */
static fmi2Status call0(Instance *c, const char *method, const char *call)
{
    int gil;
    if (!enter(c, call, &gil)) return fmi2Error;
    PyObject *result = invoke(c, (PyObject *)c->slave, method, py.Tuple_New(0), call);
    release(result);
    leave(c, gil);
    return result ? fmi2OK : fmi2Error;
}

/* ---- the instance ------------------------------------------------------------------- */

static PyObject *construct(Instance *c)
{
    PyObject *kwargs = py.Dict_New();
    PyObject *name = py.Unicode_FromString(c->name);
    PyObject *resources = py.Unicode_DecodeFSDefault(c->resources);
    PyObject *visible = py.Bool_FromLong(c->visible);
    PyObject *args = py.Tuple_New(0);
    PyObject *slave = NULL;
    if (kwargs && name && resources && visible && args &&
        !py.Dict_SetItemString(kwargs, "instance_name", name) &&
        !py.Dict_SetItemString(kwargs, "resources", resources) &&
        !py.Dict_SetItemString(kwargs, "visible", visible)) {
        slave = py.Call(EXTRA(c)->cls, args, kwargs);
    }
    if (!slave) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "fmi2Instantiate: %s(...) raised %s", c->record.slave_class, error);
    }
    PyObject *objects[] = {kwargs, name, resources, visible, args};
    for (size_t i = 0; i < 5; i++) release(objects[i]);
    return slave;
}

/* The slave class, from the build's package in this extraction's resources. */
static PyObject *slave_class(Instance *c)
{
    PyObject *load = python_helper("load");
    PyObject *items[] = {py.Unicode_FromString(c->record.package),
                         py.Unicode_DecodeFSDefault(c->resources),
                         py.Unicode_FromString(c->record.module),
                         py.Unicode_FromString(c->record.slave_class)};
    PyObject *args = pack(4, items);
    PyObject *cls = load && args ? py.Call(load, args, NULL) : NULL;
    if (!cls) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "fmi2Instantiate: cannot import %s.%s from %s: %s", c->record.module,
               c->record.slave_class, c->resources, error);
    }
    release(args);
    release(load);
    return cls;
}

/* The new slave and its log queue in place of the old ones (released); 0 if it failed. */
static int renew(Instance *c)
{
    PyObject *slave = construct(c);
    PyObject *queue = slave ? py.GetAttrString(slave, "log_queue") : NULL;
    if (slave && !queue) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "fmi2Instantiate: the slave has no log_queue (%s)", error);
    }
    if (!queue) {
        release(slave);
        return 0;
    }
    release(EXTRA(c)->queue);
    release((PyObject *)c->slave);
    EXTRA(c)->queue = queue;
    c->slave = slave;
    return 1;
}

static int start(Instance *c)
{
    c->extra = calloc(1, sizeof(Extra));
    if (!c->extra) return 0;
    int gil = py.GILState_Ensure();
    EXTRA(c)->cls = slave_class(c);
    int ok = EXTRA(c)->cls && renew(c);
    if (ok) flush_log(c);
    if (!ok) release(EXTRA(c)->cls);
    py.GILState_Release(gil);
    if (!ok) {
        free(c->extra);
        c->extra = NULL;
    }
    return ok;
}

static void forget_strings(Extra *e)
{
    for (size_t i = 0; i < e->n_strings; i++) free(e->strings[i]);
    free(e->strings);
    e->strings = NULL;
    e->n_strings = 0;
}

static void stop(Instance *c)
{
    Extra *e = EXTRA(c);
    if (python_alive()) { /* else Python's objects are gone with it: C memory only */
        int gil = py.GILState_Ensure();
        release(e->queue);
        release((PyObject *)c->slave);
        release(e->cls);
        py.GILState_Release(gil);
    }
    forget_strings(e);
    free(e);
}

/* ---- the call sequence -------------------------------------------------------------- */

static fmi2Status setup(Instance *c, fmi2Boolean has_tolerance, fmi2Real tolerance,
                        fmi2Real start_time, fmi2Boolean has_stop, fmi2Real stop_time)
{
    int gil;
    if (!enter(c, "fmi2SetupExperiment", &gil)) return fmi2Error;
    PyObject *items[] = {py.Float_FromDouble(start_time),
                         has_stop ? py.Float_FromDouble(stop_time) : python_none(),
                         has_tolerance ? py.Float_FromDouble(tolerance) : python_none()};
    PyObject *result = invoke(c, (PyObject *)c->slave, "setup_experiment", pack(3, items),
                              "fmi2SetupExperiment");
    release(result);
    leave(c, gil);
    return result ? fmi2OK : fmi2Error;
}

static fmi2Status enter_initialization(Instance *c)
{
    return call0(c, "enter_initialization_mode", "fmi2EnterInitializationMode");
}

static fmi2Status exit_initialization(Instance *c)
{
    return call0(c, "exit_initialization_mode", "fmi2ExitInitializationMode");
}

static fmi2Status terminate(Instance *c) { return call0(c, "terminate", "fmi2Terminate"); }

static fmi2Status step(Instance *c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_state)
{
    (void)no_set_state;
    int gil;
    if (!enter(c, "fmi2DoStep", &gil)) return fmi2Error;
    PyObject *items[] = {py.Float_FromDouble(t), py.Float_FromDouble(h)};
    PyObject *result = invoke(c, (PyObject *)c->slave, "do_step", pack(2, items), "fmi2DoStep");
    int done = result ? py.IsTrue(result) : -1;
    release(result);
    leave(c, gil);
    return done < 0 ? fmi2Error : done ? fmi2OK : fmi2Discard;
}

static fmi2Status reset(Instance *c)
{
    int gil;
    if (!enter(c, "fmi2Reset", &gil)) return fmi2Error;
    int ok = renew(c); /* as pythonfmu: a new instance of the slave class */
    leave(c, gil);
    return ok ? fmi2OK : fmi2Error;
}

/* ---- values ------------------------------------------------------------------------- */

static const char *const GETTERS[] = {"get_real", "get_integer", "get_boolean", "get_string"};
static const char *const SETTERS[] = {"set_real", "set_integer", "set_boolean", "set_string"};

static int kind(char type) { return type == 'R' ? 0 : type == 'I' ? 1 : type == 'B' ? 2 : 3; }

static PyObject *references(const fmi2ValueReference vr[], size_t n)
{
    PyObject *list = py.List_New((Py_ssize_t)n);
    for (size_t i = 0; list && i < n; i++) {
        py.List_SetItem(list, (Py_ssize_t)i, py.Long_FromUnsignedLong(vr[i]));
    }
    return list;
}

static PyObject *to_python(char type, const void *values, size_t i)
{
    if (type == 'R') return py.Float_FromDouble(((const double *)values)[i]);
    if (type == 'I') return py.Long_FromLong(((const int *)values)[i]);
    if (type == 'B') return py.Bool_FromLong(((const int *)values)[i]);
    return py.Unicode_FromString(((const fmi2String *)values)[i]);
}

/* A list of the ``n`` values (NULL if one cannot be made: invalid UTF-8, no memory). */
static PyObject *value_list(char type, const void *values, size_t n)
{
    PyObject *list = py.List_New((Py_ssize_t)n);
    for (size_t i = 0; list && i < n; i++) {
        PyObject *item = to_python(type, values, i);
        if (!item) {
            release(list);
            return NULL;
        }
        py.List_SetItem(list, (Py_ssize_t)i, item);
    }
    return list;
}

/* Item ``i`` of a getter's answer into ``values``; 0 if it is not of the type. */
static int from_python(Instance *c, char type, PyObject *item, void *values, size_t i)
{
    if (type == 'R') ((double *)values)[i] = py.Float_AsDouble(item);
    if (type == 'I') ((int *)values)[i] = (int)py.Long_AsLong(item);
    if (type == 'B') ((int *)values)[i] = py.IsTrue(item) > 0;
    if (type == 'S') {
        const char *text = py.Unicode_AsUTF8(item);
        char *copy = text ? strdup(text) : NULL;
        Extra *e = EXTRA(c);
        if (copy) e->strings[e->n_strings++] = copy;
        ((fmi2String *)values)[i] = copy;
        if (!copy) return 0;
    }
    return !py.Err_Occurred();
}

static fmi2Status unpack(Instance *c, char type, PyObject *list, size_t n, void *values,
                         const char *call)
{
    Py_ssize_t size = py.List_Size(list);
    if (size != (Py_ssize_t)n) {
        py.Err_Clear();
        return refuse(c, "%s: the slave's %s answered %zd values for %zu references", call,
                      GETTERS[kind(type)], size, n);
    }
    if (type == 'S') {
        forget_strings(EXTRA(c)); /* valid until the next fmi2GetString, as FMI 2.0 asks */
        EXTRA(c)->strings = calloc(n, sizeof(char *));
        if (!EXTRA(c)->strings) return refuse(c, "%s: out of memory", call);
    }
    for (size_t i = 0; i < n; i++) {
        if (!from_python(c, type, py.List_GetItem(list, (Py_ssize_t)i), values, i)) {
            char error[LINE_SIZE / 2];
            python_error(error, sizeof error);
            return refuse(c, "%s: value %zu of the slave's answer: %s", call, i, error);
        }
    }
    return fmi2OK;
}

static fmi2Status get(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      void *values)
{
    const char *call = "fmi2Get";
    int gil;
    if (!enter(c, call, &gil)) return fmi2Error;
    PyObject *items[] = {references(vr, n)};
    PyObject *list = invoke(c, (PyObject *)c->slave, GETTERS[kind(type)], pack(1, items), call);
    fmi2Status s = list ? unpack(c, type, list, n, values, call) : fmi2Error;
    release(list);
    leave(c, gil);
    return s;
}

static fmi2Status set(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      const void *values)
{
    int gil;
    if (!enter(c, "fmi2Set", &gil)) return fmi2Error;
    PyObject *list = value_list(type, values, n);
    PyObject *result = NULL;
    if (!list) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "fmi2Set%s refused: a value cannot be passed on (%s)",
               type == 'S' ? "String" : "", error);
    } else {
        PyObject *items[] = {references(vr, n), list};
        result = invoke(c, (PyObject *)c->slave, SETTERS[kind(type)], pack(2, items), "fmi2Set");
    }
    release(result);
    leave(c, gil);
    return result ? fmi2OK : fmi2Error;
}

static fmi2Status derivatives(Instance *c, const fmi2ValueReference vr[], size_t n,
                              const fmi2Integer order[], const fmi2Real values[])
{
    int gil;
    if (!enter(c, "fmi2SetRealInputDerivatives", &gil)) return fmi2Error;
    PyObject *items[] = {references(vr, n), value_list('I', order, n), value_list('R', values, n)};
    PyObject *result = invoke(c, (PyObject *)c->slave, "set_real_input_derivatives",
                              pack(3, items), "fmi2SetRealInputDerivatives");
    release(result);
    leave(c, gil);
    return result ? fmi2OK : fmi2Error;
}

/* ---- FMU state: the slave's own (a Python object) ----------------------------------- */

static fmi2Status save(Instance *c, void **state)
{
    int gil;
    if (!enter(c, "fmi2GetFMUstate", &gil)) return fmi2Error;
    PyObject *saved = invoke(c, (PyObject *)c->slave, "_get_fmu_state", py.Tuple_New(0),
                             "fmi2GetFMUstate");
    leave(c, gil);
    *state = saved;
    return saved ? fmi2OK : fmi2Error;
}

static fmi2Status restore(Instance *c, void *state)
{
    int gil;
    if (!enter(c, "fmi2SetFMUstate", &gil)) return fmi2Error;
    py.IncRef((PyObject *)state); /* pack steals one reference */
    PyObject *items[] = {(PyObject *)state};
    PyObject *result = invoke(c, (PyObject *)c->slave, "_set_fmu_state", pack(1, items),
                              "fmi2SetFMUstate");
    release(result);
    leave(c, gil);
    return result ? fmi2OK : fmi2Error;
}

static void discard(Instance *c, void *state)
{
    (void)c;
    if (!state || !python_alive()) return;
    int gil = py.GILState_Ensure();
    release((PyObject *)state);
    py.GILState_Release(gil);
}

static fmi2Status state_bytes(Instance *c, void *state, fmi2Byte *out, size_t capacity,
                              size_t *size)
{
    int gil;
    if (!enter(c, "fmi2SerializeFMUstate", &gil)) return fmi2Error;
    py.IncRef((PyObject *)state);
    PyObject *items[] = {(PyObject *)state};
    PyObject *bytes = invoke(c, (PyObject *)c->slave, "_fmu_state_to_bytes", pack(1, items),
                             "fmi2SerializeFMUstate");
    char *data = NULL;
    Py_ssize_t length = 0;
    fmi2Status s = bytes && !py.Bytes_AsStringAndSize(bytes, &data, &length) ? fmi2OK : fmi2Error;
    if (s == fmi2OK) {
        *size = (size_t)length;
        if (out && capacity >= (size_t)length) memcpy(out, data, (size_t)length);
    } else if (bytes) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "fmi2SerializeFMUstate: the slave's state is not bytes (%s)", error);
    }
    release(bytes);
    leave(c, gil);
    return s;
}

static fmi2Status state_from_bytes(Instance *c, const fmi2Byte *bytes, size_t size, void **state)
{
    int gil;
    if (!enter(c, "fmi2DeSerializeFMUstate", &gil)) return fmi2Error;
    PyObject *items[] = {py.Bytes_FromStringAndSize(bytes, (Py_ssize_t)size)};
    PyObject *loaded = invoke(c, (PyObject *)c->slave, "_fmu_state_from_bytes", pack(1, items),
                              "fmi2DeSerializeFMUstate");
    leave(c, gil);
    *state = loaded;
    return loaded ? fmi2OK : fmi2Error;
}

const Backend python_backend = {
    start,       stop,          setup, enter_initialization, exit_initialization,
    step,        terminate,     reset, get,                  set,
    save,        restore,       discard, state_bytes,        state_from_bytes,
    derivatives,
};
