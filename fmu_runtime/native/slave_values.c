/* The default backend's values: the slave's value buffers held by the runtime, its
 * Strings' copies, and its FMU states (fmu_runtime/value_buffers.py is the Python side).
 *
 * After constructing the slave the runtime asks it for its six buffers (``_buffers()``:
 * bytearrays of its Real, Integer and Boolean values, flags, control, derivatives) and
 * holds a writable buffer export of each for as long as it uses the slave: a bytearray
 * with exports can neither be resized nor freed, so the memory values.c reads and writes
 * without the GIL stays the slave's own, which its numpy views see. The sizes are checked
 * against resources/fmu_variables.txt, so the runtime and the slave agree on every slot.
 *
 * Strings are the runtime's copies (fmi2GetString answers them without Python): written
 * ones are handed to the slave at its next call (``_take_strings``), and the copies are
 * refreshed from the slave (``_string_values``) after each call but a step.
 *
 * An FMU state is the buffers' bytes and the slave's own part, saved without the buffers
 * (``_get_fmu_state(False)``: its bookkeeping, its String values, its subclass's
 * snapshot). Restoring puts the buffers back first, then calls ``_set_fmu_state``, which
 * hands the watched variables their slots' values. Serialised: a header of the layout
 * (5 uint64: Real, Integer and Boolean slots, value references, control bytes), the
 * buffers' bytes, then the slave's part as JSON (``_fmu_state_to_bytes``): exact, and
 * refused by an FMU of another layout.
 */
#include "slave.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const NAMES[BUFFERS] = {"Real values", "Integer values", "Boolean values",
                                           "flags", "control bytes", "input derivatives"};

static void expected_sizes(const Instance *c, size_t out[BUFFERS])
{
    const Values *v = &c->values;
    size_t sizes[BUFFERS] = {v->reals_n * sizeof(double), v->integers_n * sizeof(int),
                             v->booleans_n * sizeof(int), c->count,
                             CONTROL_SIZE, 2 * v->reals_n * sizeof(double)};
    memcpy(out, sizes, sizeof sizes);
}

static void release_views(Py_buffer views[], int n)
{
    for (int i = 0; i < n; i++) py.Buffer_Release(&views[i]);
}

int slave_hold_buffers(Instance *c, PyObject *slave, Py_buffer views[BUFFERS])
{
    const char *call = "fmi2Instantiate";
    size_t expected[BUFFERS];
    expected_sizes(c, expected);
    PyObject *buffers = slave_invoke(c, slave, "_buffers", py.Tuple_New(0), call);
    if (!buffers) return 0;
    int held = 0, ok = py.Tuple_Size(buffers) == BUFFERS;
    if (!ok) {
        py.Err_Clear();
        refuse(c, "%s: the slave's _buffers() is not %d buffers", call, BUFFERS);
    }
    for (; ok && held < BUFFERS; held++) {
        PyObject *item = py.Tuple_GetItem(buffers, held); /* borrowed */
        if (!item || py.GetBuffer(item, &views[held], PyBUF_WRITABLE) != 0) {
            char error[LINE_SIZE / 2];
            python_error(error, sizeof error);
            refuse(c, "%s: the slave's %s cannot be shared (%s)", call, NAMES[held], error);
            ok = 0;
            break;
        }
        if ((size_t)views[held].len != expected[held]) {
            refuse(c,
                   "%s: the slave's %s hold %zd bytes, resources/%s asks for %zu: the "
                   "slave's variables are not the FMU's",
                   call, NAMES[held], views[held].len, VARIABLES_FILE, expected[held]);
            ok = 0;
            held++; /* this one is held too */
            break;
        }
    }
    slave_release(buffers);
    if (!ok) release_views(views, held);
    return ok;
}

void slave_use_buffers(Instance *c, Py_buffer views[BUFFERS])
{
    slave_release_buffers(c);
    Extra *e = EXTRA(c);
    memcpy(e->views, views, sizeof e->views);
    e->viewing = BUFFERS;
    Values *v = &c->values;
    v->reals = e->views[0].buf;
    v->integers = e->views[1].buf;
    v->booleans = e->views[2].buf;
    v->flags = e->views[3].buf;
    v->control = e->views[4].buf;
    v->derivatives = e->views[5].buf;
}

void slave_release_buffers(Instance *c)
{
    Extra *e = EXTRA(c);
    release_views(e->views, e->viewing);
    e->viewing = 0;
    Values *v = &c->values;
    v->reals = v->derivatives = NULL;
    v->integers = v->booleans = NULL;
    v->flags = v->control = NULL;
}

/* ---- Strings ------------------------------------------------------------------------ */

int slave_push_strings(Instance *c, const char *call)
{
    Values *v = &c->values;
    PyObject *written = py.Dict_New();
    int ok = written != NULL;
    for (size_t vr = 0; ok && vr < c->count; vr++) {
        const Variable *var = &c->vars[vr];
        if (!var->known || var->type != 'S' || !v->dirty[var->slot]) continue;
        PyObject *key = py.Long_FromUnsignedLong((unsigned long)vr);
        PyObject *text = py.Unicode_FromString(v->strings[var->slot]);
        ok = key && text && py.Dict_SetItem(written, key, text) == 0;
        slave_release(key);
        slave_release(text);
        v->dirty[var->slot] = 0;
    }
    v->strings_dirty = 0;
    PyObject *items[] = {written};
    PyObject *done = ok ? slave_invoke(c, (PyObject *)c->slave, "_take_strings",
                                       slave_pack(1, items), call)
                        : NULL;
    if (!ok) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        slave_release(written);
        refuse(c, "%s: the Strings written cannot be handed to the slave (%s)", call, error);
    }
    slave_release(done);
    return done != NULL;
}

int slave_pull_strings(Instance *c, const char *call)
{
    Values *v = &c->values;
    if (!v->strings_n) return 1;
    PyObject *list = slave_invoke(c, (PyObject *)c->slave, "_string_values", py.Tuple_New(0),
                                  call);
    int ok = list && py.List_Size(list) == (Py_ssize_t)v->strings_n;
    for (size_t i = 0; ok && i < v->strings_n; i++) {
        const char *text = py.Unicode_AsUTF8(py.List_GetItem(list, (Py_ssize_t)i));
        ok = text && values_keep_string(v, i, text);
    }
    if (list && !ok) {
        py.Err_Clear();
        refuse(c, "%s: the slave's String values cannot be read", call);
    }
    slave_release(list);
    return ok;
}

/* ---- FMU state ---------------------------------------------------------------------- */

typedef struct {
    PyObject *python; /* the slave's part */
    size_t size;      /* of ``bytes`` */
    char bytes[];     /* the buffers' */
} State;

#define LAYOUT 5
#define HEADER (LAYOUT * sizeof(uint64_t))

static void layout(const Instance *c, uint64_t out[LAYOUT])
{
    const Values *v = &c->values;
    uint64_t sizes[LAYOUT] = {v->reals_n, v->integers_n, v->booleans_n, c->count, CONTROL_SIZE};
    memcpy(out, sizes, sizeof sizes);
}

static State *new_state(Instance *c, const char *bytes)
{
    size_t size = values_bytes(&c->values, c->count);
    State *state = malloc(sizeof(State) + size);
    if (!state) return NULL;
    state->python = NULL;
    state->size = size;
    if (bytes) {
        memcpy(state->bytes, bytes, size);
    } else {
        values_save(&c->values, c->count, state->bytes);
    }
    return state;
}

fmi2Status slave_save(Instance *c, void **saved)
{
    int gil;
    if (!slave_enter(c, "fmi2GetFMUstate", &gil)) return fmi2Error;
    PyObject *items[] = {py.Bool_FromLong(0)}; /* without the buffers: saved here */
    PyObject *python = slave_invoke(c, (PyObject *)c->slave, "_get_fmu_state",
                                    slave_pack(1, items), "fmi2GetFMUstate");
    State *state = python ? new_state(c, NULL) : NULL; /* after the slave published */
    if (state) state->python = python;
    if (python && !state) {
        slave_release(python);
        refuse(c, "fmi2GetFMUstate refused: out of memory");
    }
    slave_leave(c, gil);
    *saved = state;
    return state ? fmi2OK : fmi2Error;
}

/* The buffers are restored before the slave's part (which reads them); if the slave then
 * refuses its part, the buffers get their values back: a refused call changes nothing. */
fmi2Status slave_restore(Instance *c, void *saved)
{
    State *state = saved;
    size_t size = values_bytes(&c->values, c->count);
    if (state->size != size) {
        return refuse(c, "fmi2SetFMUstate refused: the state holds %zu bytes of values, this "
                      "FMU's %zu (a state of another FMU)", state->size, size);
    }
    State *now = new_state(c, NULL);
    if (!now) return refuse(c, "fmi2SetFMUstate refused: out of memory");
    int gil;
    int ok = slave_enter(c, "fmi2SetFMUstate", &gil);
    if (ok) {
        values_restore(&c->values, c->count, state->bytes);
        py.IncRef(state->python); /* pack steals one reference */
        PyObject *items[] = {state->python};
        PyObject *result = slave_invoke(c, (PyObject *)c->slave, "_set_fmu_state",
                                        slave_pack(1, items), "fmi2SetFMUstate");
        ok = result && slave_pull_strings(c, "fmi2SetFMUstate");
        if (!result) values_restore(&c->values, c->count, now->bytes);
        slave_release(result);
        slave_leave(c, gil);
    }
    free(now);
    return ok ? fmi2OK : fmi2Error;
}

void slave_discard(Instance *c, void *saved)
{
    (void)c;
    State *state = saved;
    if (!state) return;
    if (python_alive()) { /* else Python's objects are gone with it: C memory only */
        int gil = py.GILState_Ensure();
        slave_release(state->python);
        py.GILState_Release(gil);
    }
    free(state);
}

fmi2Status slave_state_bytes(Instance *c, void *saved, fmi2Byte *out, size_t capacity,
                             size_t *size)
{
    State *state = saved;
    int gil;
    if (!slave_enter(c, "fmi2SerializeFMUstate", &gil)) return fmi2Error;
    py.IncRef(state->python);
    PyObject *items[] = {state->python};
    PyObject *json = slave_invoke(c, (PyObject *)c->slave, "_fmu_state_to_bytes",
                                  slave_pack(1, items), "fmi2SerializeFMUstate");
    char *data = NULL;
    Py_ssize_t length = 0;
    fmi2Status s = json && !py.Bytes_AsStringAndSize(json, &data, &length) ? fmi2OK : fmi2Error;
    if (s == fmi2OK) {
        uint64_t header[LAYOUT];
        layout(c, header);
        *size = HEADER + state->size + (size_t)length;
        if (out && capacity >= *size) {
            memcpy(out, header, HEADER);
            memcpy(out + HEADER, state->bytes, state->size);
            memcpy(out + HEADER + state->size, data, (size_t)length);
        }
    } else if (json) {
        char error[LINE_SIZE / 2];
        python_error(error, sizeof error);
        refuse(c, "fmi2SerializeFMUstate: the slave's state is not bytes (%s)", error);
    }
    slave_release(json);
    slave_leave(c, gil);
    return s;
}

/* 1 if the slave's part ``python`` is unusable, ``call`` refused saying why: the slave's
 * _fmu_state_from_bytes answers bytes it cannot read with {"error": why} (pythonfmu's
 * binary, which calls it too, wants an answer, not an exception), which would be taken
 * here and refused only when set. */
static int unusable(Instance *c, PyObject *python, const char *call)
{
    PyObject *get = py.GetAttrString(python, "get");
    PyObject *key = py.Unicode_FromString("error");
    PyObject *error = get && key ? py.CallFunctionObjArgs(get, key, NULL) : NULL;
    int bad = !error || error != py.None;
    if (bad) {
        const char *why = error ? py.Unicode_AsUTF8(error) : NULL;
        refuse(c, "%s refused: %s", call, why ? why : "the slave's part is not a state");
    }
    py.Err_Clear();
    PyObject *objects[] = {get, key, error};
    for (size_t i = 0; i < 3; i++) slave_release(objects[i]);
    return bad;
}

fmi2Status slave_state_from_bytes(Instance *c, const fmi2Byte *bytes, size_t size,
                                  void **saved)
{
    const char *call = "fmi2DeSerializeFMUstate";
    uint64_t header[LAYOUT], ours[LAYOUT];
    layout(c, ours);
    size_t buffers = values_bytes(&c->values, c->count);
    if (size < HEADER + buffers) {
        return refuse(c, "%s refused: %zu bytes are too few for a state of this FMU", call, size);
    }
    if (size - HEADER - buffers > (size_t)PTRDIFF_MAX) { /* Py_ssize_t would wrap below */
        return refuse(c, "%s refused: size = %zu bytes, more than Python's bytes hold", call,
                      size);
    }
    memcpy(header, bytes, HEADER);
    if (memcmp(header, ours, HEADER)) {
        return refuse(c, "%s refused: a state of an FMU with other variables", call);
    }
    int gil;
    if (!slave_enter(c, call, &gil)) return fmi2Error;
    State *state = new_state(c, bytes + HEADER);
    const char *json = bytes + HEADER + buffers;
    PyObject *items[] = {py.Bytes_FromStringAndSize(json, (Py_ssize_t)(size - HEADER - buffers))};
    PyObject *python = state ? slave_invoke(c, (PyObject *)c->slave, "_fmu_state_from_bytes",
                                            slave_pack(1, items), call)
                             : NULL;
    if (!state) {
        slave_release(items[0]);
        refuse(c, "%s refused: out of memory", call);
    } else if (!python || unusable(c, python, call)) {
        slave_release(python);
        free(state);
        state = NULL;
    } else {
        state->python = python;
    }
    slave_leave(c, gil);
    *saved = state;
    return state ? fmi2OK : fmi2Error;
}
