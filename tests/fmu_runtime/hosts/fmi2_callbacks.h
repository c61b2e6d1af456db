/* What every test host hands an FMU: FMI 2.0's value reference and callback structure
 * (fmi2ValueReference, fmi2CallbackFunctions), with plain C types so the hosts need no
 * FMI headers; and how the POSIX hosts look up an FMU's functions and read its GUID. */
#ifndef FMI2_CALLBACKS_H
#define FMI2_CALLBACKS_H

#ifndef _WIN32
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
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

/* ``dir``/modelDescription.xml read into ``text`` (``size`` bytes at most, 0-terminated;
 * empty if it cannot be read) and its guid attribute into ``guid`` (128 bytes; left as it
 * is if there is none). */
static inline void read_description(const char *dir, char *text, size_t size, char *guid)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/modelDescription.xml", dir);
    FILE *md = fopen(path, "r");
    size_t n = md ? fread(text, 1, size - 1, md) : 0;
    if (md) fclose(md);
    text[n] = '\0';
    char *g = strstr(text, "guid=\"");
    if (g) sscanf(g + 6, "%127[^\"]", guid);
}
#endif

#endif
