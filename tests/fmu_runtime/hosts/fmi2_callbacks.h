/* What every test host hands an FMU: FMI 2.0's value reference and callback structure
 * (fmi2ValueReference, fmi2CallbackFunctions), with plain C types so the hosts need no
 * FMI headers. */
#ifndef FMI2_CALLBACKS_H
#define FMI2_CALLBACKS_H

typedef unsigned int Vr;
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocate)(size_t, size_t);
    void (*release)(void *);
    void *step_finished;
    void *environment;
} Callbacks;

#endif
