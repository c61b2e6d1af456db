/* The variables' values in C: fmi2Get*, fmi2Set* and fmi2SetRealInputDerivatives answered
 * from the value buffers the slave shares with the runtime (loader.h's Values;
 * fmu_runtime/value_buffers.py is the Python side), without taking the GIL.
 *
 * loader.c has checked each call before it comes here (the value references known and of
 * the call's type, the writes allowed now, finite and within min/max). What is left:
 *
 * - a read copies the slots out; a Real that is not finite is refused with a line (a
 *   watched variable whose getter failed, or a model that produced NaN: never a NaN
 *   handed on silently);
 * - a write copies the values into the slots, flags the variables WRITTEN, a watched one
 *   (whose value lives in the slave's own storage) CHANGED with CONTROL_CHANGES, so that
 *   the slave hands it to its setter when it is next called, and sets CONTROL_STALE (the
 *   outputs to start from must be computed again before a read in initialisation mode);
 *   a String is copied and marked dirty: the slave takes it when it is next called;
 * - input derivatives go to the derivative buffer with their flag; the slave reads them
 *   in its step and clears them after it.
 *
 * Written by hand because no library does it: the buffers' layout is this runtime's own.
 */
#define _GNU_SOURCE /* strdup */
#include "loader.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void mark_written(Values *v, fmi2ValueReference vr, char type)
{
    unsigned char flags = v->flags[vr] | FLAG_WRITTEN;
    if (type != 'S' && (flags & FLAG_WATCHED) && !(flags & FLAG_CHANGED)) {
        flags |= FLAG_CHANGED;
        v->control[CONTROL_CHANGES] = 1;
    }
    v->flags[vr] = flags;
}

fmi2Status values_get(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      void *values)
{
    const Values *v = &c->values;
    for (size_t i = 0; i < n; i++) {
        const Variable *var = &c->vars[vr[i]];
        if (type == 'R') {
            double x = v->reals[var->slot];
            if (!isfinite(x)) {
                char shown[32];
                return refuse(c, "getReal: %s = %s is not finite", var->name, show(x, shown));
            }
            ((double *)values)[i] = x;
        } else if (type == 'I') {
            ((int *)values)[i] = v->integers[var->slot];
        } else if (type == 'B') {
            ((int *)values)[i] = v->booleans[var->slot] != 0;
        } else {
            const char *text = v->strings[var->slot];
            ((fmi2String *)values)[i] = text ? text : "";
        }
    }
    return fmi2OK;
}

double values_slot(const Instance *c, fmi2ValueReference vr)
{
    const Variable *var = &c->vars[vr];
    const Values *v = &c->values;
    return var->type == 'R'   ? v->reals[var->slot]
           : var->type == 'I' ? (double)v->integers[var->slot]
                              : (double)(v->booleans[var->slot] != 0);
}

fmi2Status values_set(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      const void *values)
{
    Values *v = &c->values;
    for (size_t i = 0; i < n; i++) {
        const Variable *var = &c->vars[vr[i]];
        if (type == 'R') {
            v->reals[var->slot] = ((const double *)values)[i];
        } else if (type == 'I') {
            v->integers[var->slot] = ((const int *)values)[i];
        } else if (type == 'B') {
            v->booleans[var->slot] = ((const int *)values)[i] != 0;
        } else {
            if (!values_keep_string(v, (size_t)var->slot, ((const fmi2String *)values)[i])) {
                return refuse(c, "fmi2SetString refused: out of memory for %s", var->name);
            }
            v->dirty[var->slot] = 1;
            v->strings_dirty = 1;
        }
        mark_written(v, vr[i], type);
    }
    v->control[CONTROL_STALE] = 1;
    return fmi2OK;
}

void values_derivatives(Instance *c, const fmi2ValueReference vr[], size_t n,
                        const fmi2Integer order[], const fmi2Real values[])
{
    Values *v = &c->values;
    for (size_t i = 0; i < n; i++) {
        size_t slot = (size_t)c->vars[vr[i]].slot;
        v->derivatives[(size_t)(order[i] - 1) * v->reals_n + slot] = values[i];
        v->flags[vr[i]] |= order[i] == 1 ? FLAG_DERIVATIVE_1 : FLAG_DERIVATIVE_2;
    }
    if (n) v->control[CONTROL_DERIVATIVES] = 1;
}

void values_clear_derivatives(Instance *c)
{
    Values *v = &c->values;
    if (!v->control || !v->control[CONTROL_DERIVATIVES]) return;
    memset(v->derivatives, 0, 2 * v->reals_n * sizeof(double));
    for (size_t vr = 0; vr < c->count; vr++) {
        v->flags[vr] &= (unsigned char)~(FLAG_DERIVATIVE_1 | FLAG_DERIVATIVE_2);
    }
    v->control[CONTROL_DERIVATIVES] = 0;
}

/* ---- FMU state ---------------------------------------------------------------------- */

typedef struct {
    void *memory;
    size_t size;
} Part;

/* The buffers in the order of an FMU state (value_buffers.py's dump order). */
static size_t parts(const Values *v, size_t flags_n, Part out[6])
{
    Part list[6] = {
        {v->reals, v->reals_n * sizeof(double)},
        {v->integers, v->integers_n * sizeof(int)},
        {v->booleans, v->booleans_n * sizeof(int)},
        {v->flags, flags_n},
        {v->control, CONTROL_SIZE},
        {v->derivatives, 2 * v->reals_n * sizeof(double)},
    };
    size_t total = 0;
    for (int i = 0; i < 6; i++) {
        out[i] = list[i];
        total += list[i].size;
    }
    return total;
}

size_t values_bytes(const Values *v, size_t flags_n)
{
    Part p[6];
    return parts(v, flags_n, p);
}

void values_save(const Values *v, size_t flags_n, char *to)
{
    Part p[6];
    parts(v, flags_n, p);
    for (int i = 0; i < 6; i++) {
        if (p[i].size) memcpy(to, p[i].memory, p[i].size);
        to += p[i].size;
    }
}

void values_restore(Values *v, size_t flags_n, const char *from)
{
    Part p[6];
    parts(v, flags_n, p);
    for (int i = 0; i < 6; i++) {
        if (p[i].size) memcpy(p[i].memory, from, p[i].size);
        from += p[i].size;
    }
}

/* ---- the String copies -------------------------------------------------------------- */

/* GCC 12's analyser reports ``copy`` leaked: a loop storing at a symbolic index (values_set,
 * one String after another) makes it forget the store before; the copy is kept in
 * v->strings, freed by values_free_strings. */
#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 10
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wanalyzer-malloc-leak"
#endif
int values_keep_string(Values *v, size_t slot, const char *text)
{
    if (v->strings[slot] && !strcmp(v->strings[slot], text)) return 1;
    char *copy = strdup(text);
    if (!copy) return 0;
    free(v->strings[slot]);
    v->strings[slot] = copy;
    return 1;
}
#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 10
#pragma GCC diagnostic pop
#endif

void values_free_strings(Values *v)
{
    for (size_t i = 0; v->strings && i < v->strings_n; i++) free(v->strings[i]);
    free(v->strings);
    free(v->dirty);
    v->strings = NULL;
    v->dirty = NULL;
}
