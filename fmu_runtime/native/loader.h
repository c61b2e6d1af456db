/* The native loader in front of pythonfmu's wrapper library: shared declarations.
 *
 * The FMI 2.0 types are declared here rather than taken from the standard's headers so
 * that the loader compiles from this folder alone, with any C compiler (cc, zig cc,
 * a win64 cross-compiler); they are the ABI of fmi2TypesPlatform.h and
 * fmi2FunctionTypes.h (FMI 2.0.x, "default" platform).
 */
#ifndef AUV_FMU_LOADER_H
#define AUV_FMU_LOADER_H

#include <stddef.h>

#ifdef _WIN32
#define FMI2_EXPORT __declspec(dllexport)
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

/* The FMI 2.0 co-simulation functions of pythonfmu's wrapper library, as resolved by
 * runtime.c (a function the wrapper does not export is NULL). */
typedef struct {
    fmi2Status (*setDebugLogging)(fmi2Component, fmi2Boolean, size_t, const fmi2String[]);
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
    fmi2Status (*getDirectionalDerivative)(fmi2Component, const fmi2ValueReference[], size_t,
                                           const fmi2ValueReference[], size_t, const fmi2Real[],
                                           fmi2Real[]);
    fmi2Status (*setRealInputDerivatives)(fmi2Component, const fmi2ValueReference[], size_t,
                                          const fmi2Integer[], const fmi2Real[]);
    fmi2Status (*getRealOutputDerivatives)(fmi2Component, const fmi2ValueReference[], size_t,
                                           const fmi2Integer[], fmi2Real[]);
    fmi2Status (*doStep)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
    fmi2Status (*cancelStep)(fmi2Component);
    fmi2Status (*getStatus)(fmi2Component, const fmi2StatusKind, fmi2Status *);
    fmi2Status (*getRealStatus)(fmi2Component, const fmi2StatusKind, fmi2Real *);
    fmi2Status (*getIntegerStatus)(fmi2Component, const fmi2StatusKind, fmi2Integer *);
    fmi2Status (*getBooleanStatus)(fmi2Component, const fmi2StatusKind, fmi2Boolean *);
    fmi2Status (*getStringStatus)(fmi2Component, const fmi2StatusKind, fmi2String *);
} Wrapper;

/* The environment variable that names the Python to use instead of the one recorded at
 * build time: a Python executable, or a virtual environment's folder. */
#define LOADER_PYTHON_VARIABLE "AUV_FMU_PYTHON"

/* Make sure an initialised CPython is in the process and pythonfmu's wrapper library is
 * loaded (once per process; thread-safe). ``resources`` is the FMU's resources folder
 * (a path, not a URI). Returns the wrapper's functions, or NULL with one line in ``why``
 * saying what was looked for and what to set. */
const Wrapper *loader_runtime(const char *resources, char *why, size_t why_size);

#endif
