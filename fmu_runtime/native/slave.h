/* What the default backend's two files share: slave.c calls the Python slave,
 * slave_values.c holds its value buffers, its Strings and its FMU states. */
#ifndef AUV_FMU_SLAVE_H
#define AUV_FMU_SLAVE_H

#include "loader.h"
#include "python.h"

#define BUFFERS 6 /* Real, Integer, Boolean values, flags, control, derivatives */

typedef struct {
    PyObject *cls;               /* the slave class */
    PyObject *queue;             /* the slave's log queue (a list of pythonfmu LogMsg) */
    PyObject *do_step;           /* the slave's bound do_step: the one call of a step */
    Py_buffer views[BUFFERS];    /* exports of the slave's value buffers, held */
    int viewing;                 /* how many of ``views`` are held */
} Extra;

#define EXTRA(c) ((Extra *)(c)->extra)

/* slave.c: take the GIL (and hand the slave the Strings written since its last call), or
 * refuse when Python is gone or going; ``leave`` passes the slave's log on and releases
 * the GIL. */
int slave_enter(Instance *c, const char *call, int *gil);
void slave_leave(Instance *c, int gil);
/* ``target.method(*args)`` (args stolen); NULL with an Error line naming the exception. */
PyObject *slave_invoke(Instance *c, PyObject *target, const char *method, PyObject *args,
                       const char *call);
/* A tuple of ``n`` new references (stolen); NULL if one is NULL. */
PyObject *slave_pack(int n, PyObject *items[]);
void slave_release(PyObject *object);

/* slave_values.c, with the GIL held: */
/* The value buffers of ``slave`` held in ``views``, checked against the FMU's variables;
 * 0 with a line (nothing held then). */
int slave_hold_buffers(Instance *c, PyObject *slave, Py_buffer views[BUFFERS]);
/* The instance's values point into ``views`` (now the instance's), the old ones released. */
void slave_use_buffers(Instance *c, Py_buffer views[BUFFERS]);
void slave_release_buffers(Instance *c);
/* The Strings written since the slave's last call to it (1), or 0 with a line. */
int slave_push_strings(Instance *c, const char *call);
/* The slave's String values into the runtime's copies (1), or 0 with a line. */
int slave_pull_strings(Instance *c, const char *call);

/* slave_values.c: the backend's FMU state functions (loader.h's Backend). */
fmi2Status slave_save(Instance *c, void **state);
fmi2Status slave_restore(Instance *c, void *state);
void slave_discard(Instance *c, void *state);
fmi2Status slave_state_bytes(Instance *c, void *state, fmi2Byte *out, size_t capacity,
                             size_t *size);
fmi2Status slave_state_from_bytes(Instance *c, const fmi2Byte *bytes, size_t size,
                                  void **state);

#endif
