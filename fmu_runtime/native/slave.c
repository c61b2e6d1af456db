/* The default backend: the FMU's Python slave class, constructed and called directly
 * through the CPython C API (no pythonfmu binary involved).
 *
 * Written by hand because pythonfmu's wrapper, the library that does this job in
 * pythonfmu, cannot be rebuilt for old glibc and crashes on NULL arguments, on exceptions
 * and at process exit. What it does with the slave is kept: the same constructor keywords
 * (instance_name, resources, visible), the same methods (setup_experiment, do_step, ...,
 * _get_fmu_state, _fmu_state_to_bytes), and the slave's log queue passed to the host's
 * logger after each call.
 *
 * Values cross the boundary in C: the runtime holds the slave's value buffers
 * (slave_values.c) and answers fmi2Get*, fmi2Set* and fmi2SetRealInputDerivatives from
 * them without taking the GIL (values.c). Python is entered for the life cycle (setup,
 * initialisation, doStep: the one call of a step, terminate, reset), a read in
 * initialisation mode after a write (the slave computes the outputs it will start from,
 * ``_initial_outputs``), and the FMU state.
 *
 * The slave's package is imported from the FMU's own resources folder under the build's
 * unique name (resources/fmu_runtime.txt), without touching sys.path: two builds in one
 * process never share a module, two extractions of one build share the same code.
 *
 * Python may have shut down under an instance (a Python host that exits without freeing
 * it): every call checks before taking the GIL, and then frees only C memory.
 */
#include "slave.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- calling Python ----------------------------------------------------------------- */

void slave_release(PyObject *object)
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
        slave_release(status);
        slave_release(category);
        slave_release(text);
    }
    if (n > 0) py.List_SetSlice(queue, 0, n, NULL);
    py.Err_Clear();
}

void slave_leave(Instance *c, int gil)
{
    flush_log(c);
    py.GILState_Release(gil);
}

int slave_enter(Instance *c, const char *call, int *gil)
{
    if (!python_alive() || !c->slave) {
        refuse(c, "%s refused: Python has shut down in this process", call);
        return 0;
    }
    *gil = py.GILState_Ensure();
    if (c->values.strings_dirty && !slave_push_strings(c, call)) {
        slave_leave(c, *gil);
        return 0;
    }
    return 1;
}

PyObject *slave_invoke(Instance *c, PyObject *target, const char *method, PyObject *args,
                       const char *call)
{
    PyObject *function = target && args ? py.GetAttrString(target, method) : NULL;
    PyObject *result = function ? py.Call(function, args, NULL) : NULL;
    if (!result) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "%s: the slave's %s raised %s", call, method, error);
    }
    slave_release(function);
    slave_release(args);
    return result;
}

PyObject *slave_pack(int n, PyObject *items[])
{
    PyObject *tuple = py.Tuple_New(n);
    for (int i = 0; i < n; i++) {
        if (!tuple || !items[i]) {
            for (int j = i; j < n; j++) slave_release(items[j]);
            slave_release(tuple);
            return NULL;
        }
        py.Tuple_SetItem(tuple, i, items[i]);
    }
    return tuple;
}

/* A method without arguments, then (``pull``) the Strings' copies refreshed: fmi2OK, or
 * fmi2Error when it raised. */
static fmi2Status call(Instance *c, const char *method, const char *name, int pull)
{
    int gil;
    if (!slave_enter(c, name, &gil)) return fmi2Error;
    PyObject *result = slave_invoke(c, (PyObject *)c->slave, method, py.Tuple_New(0), name);
    int ok = result && (!pull || slave_pull_strings(c, name));
    slave_release(result);
    slave_leave(c, gil);
    return ok ? fmi2OK : fmi2Error;
}

static fmi2Status call0(Instance *c, const char *method, const char *name)
{
    return call(c, method, name, 1);
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
    for (size_t i = 0; i < 5; i++) slave_release(objects[i]);
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
    PyObject *args = slave_pack(4, items);
    PyObject *cls = load && args ? py.Call(load, args, NULL) : NULL;
    if (!cls) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "fmi2Instantiate: cannot import %s.%s from %s: %s", c->record.module,
               c->record.slave_class, c->resources, error);
    }
    slave_release(args);
    slave_release(load);
    return cls;
}

/* The new slave, its log queue, its do_step and its value buffers in place of the old
 * ones (released); 0 if it failed, the old ones kept then. */
static int renew(Instance *c)
{
    Extra *e = EXTRA(c);
    PyObject *slave = construct(c);
    PyObject *queue = slave ? py.GetAttrString(slave, "log_queue") : NULL;
    PyObject *do_step = queue ? py.GetAttrString(slave, "do_step") : NULL;
    Py_buffer views[BUFFERS];
    if (slave && !do_step) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "fmi2Instantiate: the slave has no log_queue or do_step (%s)", error);
    }
    if (!do_step || !slave_hold_buffers(c, slave, views)) {
        PyObject *objects[] = {do_step, queue, slave};
        for (size_t i = 0; i < 3; i++) slave_release(objects[i]);
        return 0;
    }
    slave_use_buffers(c, views);
    PyObject *old[] = {e->do_step, e->queue, (PyObject *)c->slave};
    for (size_t i = 0; i < 3; i++) slave_release(old[i]);
    e->do_step = do_step;
    e->queue = queue;
    c->slave = slave;
    return slave_pull_strings(c, "fmi2Instantiate");
}

static int start(Instance *c)
{
    c->extra = calloc(1, sizeof(Extra));
    if (!c->extra) return 0;
    int gil = py.GILState_Ensure();
    EXTRA(c)->cls = slave_class(c);
    int ok = EXTRA(c)->cls && renew(c);
    flush_log(c);
    if (!ok) {
        slave_release_buffers(c);
        PyObject *objects[] = {EXTRA(c)->do_step, EXTRA(c)->queue, (PyObject *)c->slave,
                               EXTRA(c)->cls};
        for (size_t i = 0; i < 4; i++) slave_release(objects[i]);
        c->slave = NULL;
    }
    py.GILState_Release(gil);
    if (!ok) {
        free(c->extra);
        c->extra = NULL;
    }
    return ok;
}

static void stop(Instance *c)
{
    Extra *e = EXTRA(c);
    if (python_alive()) { /* else Python's objects are gone with it: C memory only */
        int gil = py.GILState_Ensure();
        slave_release_buffers(c);
        PyObject *objects[] = {e->do_step, e->queue, (PyObject *)c->slave, e->cls};
        for (size_t i = 0; i < 4; i++) slave_release(objects[i]);
        py.GILState_Release(gil);
    }
    free(e);
}

/* ---- the call sequence -------------------------------------------------------------- */

static fmi2Status setup(Instance *c, fmi2Boolean has_tolerance, fmi2Real tolerance,
                        fmi2Real start_time, fmi2Boolean has_stop, fmi2Real stop_time)
{
    int gil;
    if (!slave_enter(c, "fmi2SetupExperiment", &gil)) return fmi2Error;
    PyObject *items[] = {py.Float_FromDouble(start_time),
                         has_stop ? py.Float_FromDouble(stop_time) : python_none(),
                         has_tolerance ? py.Float_FromDouble(tolerance) : python_none()};
    PyObject *result = slave_invoke(c, (PyObject *)c->slave, "setup_experiment",
                                    slave_pack(3, items), "fmi2SetupExperiment");
    slave_release(result);
    slave_leave(c, gil);
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

/* The one call into Python of a step: the slave's do_step, bound once at instantiation;
 * then the input derivatives cleared here (the slave leaves them to the runtime). */
static fmi2Status step(Instance *c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_state)
{
    (void)no_set_state;
    int gil;
    if (!slave_enter(c, "fmi2DoStep", &gil)) return fmi2Error;
    PyObject *at = py.Float_FromDouble(t), *size = py.Float_FromDouble(h);
    PyObject *result = at && size ? py.CallFunctionObjArgs(EXTRA(c)->do_step, at, size, NULL)
                                  : NULL;
    if (!result) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "fmi2DoStep: the slave's do_step raised %s", error);
    }
    int done = result ? py.IsTrue(result) : -1;
    PyObject *objects[] = {result, at, size};
    for (size_t i = 0; i < 3; i++) slave_release(objects[i]);
    values_clear_derivatives(c); /* they belonged to this step, done or not */
    slave_leave(c, gil);
    return done < 0 ? fmi2Error : done ? fmi2OK : fmi2Discard;
}

static fmi2Status reset(Instance *c)
{
    int gil;
    if (!slave_enter(c, "fmi2Reset", &gil)) return fmi2Error;
    int ok = renew(c); /* as pythonfmu: a new instance of the slave class */
    slave_leave(c, gil);
    return ok ? fmi2OK : fmi2Error;
}

/* ---- values: answered in C (values.c) ----------------------------------------------- */

static fmi2Status get(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      void *values)
{
    if (c->phase == INITIALIZATION && c->values.control[CONTROL_STALE]) {
        /* a read in initialisation mode after a write: the outputs to start from first
         * (Strings change only when written, which the runtime knows) */
        fmi2Status s = call(c, "_initial_outputs", "fmi2Get", 0);
        if (s != fmi2OK) return s;
    }
    return values_get(c, type, vr, n, values);
}

static fmi2Status set(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      const void *values)
{
    return values_set(c, type, vr, n, values);
}

static fmi2Status derivatives(Instance *c, const fmi2ValueReference vr[], size_t n,
                              const fmi2Integer order[], const fmi2Real values[])
{
    values_derivatives(c, vr, n, order, values);
    return fmi2OK;
}

/* The slave's set_debug_logging with the categories whose debug messages pass: it then
 * formats those only (fmu_runtime/safe_slave.py). */
static fmi2Status debug(Instance *c)
{
    char names[sizeof c->record.log_categories];
    debug_categories(c, names, sizeof names);
    int gil;
    if (!slave_enter(c, "fmi2SetDebugLogging", &gil)) return fmi2Error;
    PyObject *items[] = {py.Unicode_FromString(names)};
    PyObject *result = slave_invoke(c, (PyObject *)c->slave, "set_debug_logging",
                                    slave_pack(1, items), "fmi2SetDebugLogging");
    slave_release(result);
    slave_leave(c, gil);
    return result ? fmi2OK : fmi2Error;
}

const Backend python_backend = {
    start,       stop,      setup,      enter_initialization, exit_initialization,
    step,        terminate, reset,      get,                  set,
    slave_save,  slave_restore, slave_discard, slave_state_bytes, slave_state_from_bytes,
    derivatives, debug,
};
