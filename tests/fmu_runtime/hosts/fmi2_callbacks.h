/* What every test host hands an FMU: FMI 2.0's value reference and callback structure
 * (fmi2ValueReference, fmi2CallbackFunctions), with plain C types so the hosts need no
 * FMI headers; and how the POSIX hosts look up an FMU's functions. */
#ifndef FMI2_CALLBACKS_H
#define FMI2_CALLBACKS_H

#ifndef _WIN32
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#endif

typedef unsigned int Vr;
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocate)(size_t, size_t);
    void (*release)(void *);
    void *step_finished;
    void *environment;
} Callbacks;

#ifndef _WIN32
/* The function ``name`` of the FMU's ``library``; a line naming it and exit 2 if missing. */
static inline void *need(void *library, const char *name)
{
    void *f = dlsym(library, name);
    if (!f) {
        printf("missing %s\n", name);
        exit(2);
    }
    return f;
}
#endif

#endif
