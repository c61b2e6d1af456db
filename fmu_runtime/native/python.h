/* The CPython C API the runtime uses, resolved at run time with dlsym from the libpython
 * in the process: the runtime links no libpython, so one binary serves every CPython
 * >= 3.9. Only functions are used (never a macro or a struct field): Py_INCREF is
 * Py_IncRef, Py_None is the exported _Py_NoneStruct.
 */
#ifndef AUV_FMU_PYTHON_H
#define AUV_FMU_PYTHON_H

#include <stddef.h>
#include <wchar.h>

typedef struct _object PyObject;
typedef ptrdiff_t Py_ssize_t;

/* CPython's Py_buffer: the same layout in every CPython 3 (part of the stable ABI since
 * 3.11), filled by PyObject_GetBuffer. */
typedef struct {
    void *buf;
    PyObject *obj;
    Py_ssize_t len;
    Py_ssize_t itemsize;
    int readonly;
    int ndim;
    char *format;
    Py_ssize_t *shape;
    Py_ssize_t *strides;
    Py_ssize_t *suboffsets;
    void *internal;
} Py_buffer;
#define PyBUF_WRITABLE 0x0001

typedef struct {
    /* before initialisation */
    int (*IsInitialized)(void);
    const char *(*GetVersion)(void);
    wchar_t *(*DecodeLocale)(const char *, size_t *);
    void (*SetPythonHome)(const wchar_t *);
    void (*InitializeEx)(int);
    void (*RawFree)(void *);
    int (*IsFinalizing)(void); /* Py_IsFinalizing (3.13+) or _Py_IsFinalizing */
    int *UTF8Mode;             /* Py_UTF8Mode, a variable (NULL if a CPython lacks it) */
    /* threads */
    void *(*SaveThread)(void);
    int (*GILState_Ensure)(void);
    void (*GILState_Release)(int);
    /* objects */
    void (*IncRef)(PyObject *);
    void (*DecRef)(PyObject *);
    PyObject *None;
    PyObject *(*GetAttrString)(PyObject *, const char *);
    PyObject *(*Call)(PyObject *, PyObject *, PyObject *);
    PyObject *(*CallFunctionObjArgs)(PyObject *, ...); /* arguments end with NULL */
    int (*GetBuffer)(PyObject *, Py_buffer *, int);
    void (*Buffer_Release)(Py_buffer *);
    int (*IsTrue)(PyObject *);
    PyObject *(*Str)(PyObject *);
    PyObject *(*Float_FromDouble)(double);
    double (*Float_AsDouble)(PyObject *);
    PyObject *(*Long_FromLong)(long);
    PyObject *(*Long_FromUnsignedLong)(unsigned long);
    long (*Long_AsLong)(PyObject *);
    PyObject *(*Bool_FromLong)(long);
    PyObject *(*Unicode_FromString)(const char *);
    PyObject *(*Unicode_DecodeFSDefault)(const char *);
    const char *(*Unicode_AsUTF8)(PyObject *);
    PyObject *(*Bytes_FromStringAndSize)(const char *, Py_ssize_t);
    int (*Bytes_AsStringAndSize)(PyObject *, char **, Py_ssize_t *);
    PyObject *(*List_New)(Py_ssize_t);
    int (*List_SetItem)(PyObject *, Py_ssize_t, PyObject *);
    PyObject *(*List_GetItem)(PyObject *, Py_ssize_t);
    Py_ssize_t (*List_Size)(PyObject *);
    int (*List_SetSlice)(PyObject *, Py_ssize_t, Py_ssize_t, PyObject *);
    PyObject *(*Tuple_New)(Py_ssize_t);
    int (*Tuple_SetItem)(PyObject *, Py_ssize_t, PyObject *);
    PyObject *(*Tuple_GetItem)(PyObject *, Py_ssize_t);
    Py_ssize_t (*Tuple_Size)(PyObject *);
    PyObject *(*Dict_New)(void);
    int (*Dict_SetItemString)(PyObject *, const char *, PyObject *);
    int (*Dict_SetItem)(PyObject *, PyObject *, PyObject *);
    PyObject *(*Module_New)(const char *);
    PyObject *(*Module_GetDict)(PyObject *);
    PyObject *(*Import_ImportModule)(const char *);
    PyObject *(*Import_AddModule)(const char *); /* borrowed */
    int (*SetAttrString)(PyObject *, const char *, PyObject *);
    PyObject *(*Long_FromVoidPtr)(void *);
    PyObject *(*Set_New)(PyObject *);
    int (*Set_Add)(PyObject *, PyObject *);
    int (*Set_Contains)(PyObject *, PyObject *);
    int (*Set_Discard)(PyObject *, PyObject *);
    PyObject *(*CompileString)(const char *, const char *, int);
    PyObject *(*Eval_EvalCode)(PyObject *, PyObject *, PyObject *);
    /* errors */
    PyObject *(*Err_Occurred)(void);
    void (*Err_Fetch)(PyObject **, PyObject **, PyObject **);
    void (*Err_Clear)(void);
} PythonApi;

extern PythonApi py;

/* Resolve every function from ``library`` (a platform_library_open handle, or one from
 * platform_loaded_python); 0 and the first missing name in ``missing`` if one is absent. */
int python_resolve(void *library, const char **missing);

/* 1 when the resolved interpreter is initialised and not shutting down: only then may
 * the runtime take the GIL. */
int python_alive(void);

/* 1 once the interpreter the runtime uses has shut down or is shutting down (a Python
 * host exiting without freeing its instances): the runtime then calls nothing that may
 * run Python, the host's logger included (a Python host's logger is Python code). */
int python_gone(void);

/* "major.minor" of the resolved libpython, from Py_GetVersion (safe before start-up): 1,
 * or 0 (both 0) when its version does not start so; ``said`` gets the version's first
 * word (cut to ``size``) either way. */
int python_version(int *major, int *minor, char *said, size_t size);

/* The Python-side helpers of the runtime (python.c's HELPERS), compiled once per copy of
 * this library in the process; a new reference to the function ``name``, or NULL with the
 * Python error set. Call with the GIL held. */
PyObject *python_helper(const char *name);

/* The FMU states alive in the process, by address, in a set every copy of this library
 * shares (in the interpreter: module auv_fmu_runtime_states, attribute ``alive``): each
 * extraction of each FMU loads a copy of its own, and a state one took may be set, and
 * freed, through another's instance. ``what``: STATE_KEEP, STATE_FORGET (1 if it was
 * there), STATE_ALIVE (1 if it is). Takes the GIL; 0 when Python fails. */
enum { STATE_KEEP, STATE_FORGET, STATE_ALIVE };
int python_states(int what, void *state);

/* The pending Python exception as "Type: message" in ``out`` (cleared). */
void python_error(char *out, size_t size);

/* A new reference to None. */
PyObject *python_none(void);

#endif
