/* What the runtime needs from the operating system, in one place: platform_posix.c (linux64)
 * or platform_win32.c (win64, cross-compiled with zig) implements it; the build compiles
 * one of the two. Every path and text crossing this interface is UTF-8: the Win32 side
 * converts to and from UTF-16 at each call into Windows, and CPython on Windows decodes
 * paths as UTF-8 too (PEP 529; Py_DecodeLocale without the legacy flag).
 */
#ifndef AUV_FMU_PLATFORM_H
#define AUV_FMU_PLATFORM_H

#include <stddef.h>
#include <stdio.h>

/* PYTHONFMU_URI: how pythonfmu 0.7's fmi2Instantiate reads a resource URI (forward.c): it
 * strips these characters and opens the rest as a narrow path, which on Windows is read in
 * the ANSI code page (PYTHONFMU_ASCII_ONLY). */
#ifdef _WIN32
#define PATH_SEPARATOR "\\"
#define LIBRARY_SUFFIX ".dll"
#define PYTHONFMU_URI "file:///"
#define PYTHONFMU_ASCII_ONLY 1
#else
#define PATH_SEPARATOR "/"
#define LIBRARY_SUFFIX ".so"
#define PYTHONFMU_URI "file://"
#define PYTHONFMU_ASCII_ONLY 0
#endif

/* The locks of this copy of the runtime: runtime.c's search for Python, forward.c's
 * loading of pythonfmu's library. */
enum { LOCK_RUNTIME, LOCK_WRAPPER, LOCKS };
void platform_lock(int which);
void platform_unlock(int which);

/* Held while a copy of this runtime checks whether CPython is initialised and initialises
 * it: each FMU, and each extraction of one, loads a copy of its own with its own locks
 * above, and two copies initialising CPython at once from two threads abort the process.
 * POSIX: flock on the libpython file (two descriptors of one file exclude each other, in
 * one process too; another process starting the same libpython waits for this one's
 * initialisation); Windows: a mutex named after the process. NULL when it cannot be taken:
 * then unheld, as before. */
void *platform_hold_python(const char *libpython);
void platform_release_python(void *held);

/* The environment variable ``name`` in ``out`` (truncated to size), or NULL when unset. */
const char *platform_getenv(const char *name, char *out, size_t size);

FILE *platform_fopen(const char *path, const char *mode);
/* Whether ``path`` names something; the file of this runtime library. */
int path_exists(const char *path);
int own_path(char *out, size_t size);
int platform_is_directory(const char *path);
/* 1 if two paths name one file. */
int platform_same_file(const char *a, const char *b);

/* The Python executables of a virtual environment's folder, in the order tried
 * (NULL-terminated): bin/python3, bin/python; Scripts\python.exe. */
extern const char *const VENV_PYTHONS[];
/* The Pythons looked for on PATH, in order: python3, python; python, py -3. */
typedef struct {
    const char *name;
    const char *argument; /* given before the probe's -c, or NULL */
} PathPython;
extern const PathPython PATH_PYTHONS[2];

/* ``name`` as a program on PATH (with ".exe" on Windows), into ``out``; 0 if not found. */
int platform_on_path(const char *name, char *out, size_t size);

/* The decoded path of a file: URI (loader.c strips "file:", a "localhost" host and %XX;
 * another host is left as "//host/x") made a local path in place: on Windows "/C:/x"
 * becomes "C:\x" and "//server/x" a UNC path; nothing on POSIX. */
void platform_local_path(char *path, size_t size);

/* Shared libraries (dlopen / LoadLibraryExW). ``global``: its symbols serve the libraries
 * loaded after it (RTLD_GLOBAL; Windows resolves by module name anyway). */
void *platform_library_open(const char *path, int global);
void *platform_library_symbol(void *library, const char *name);
void platform_library_close(void *library);
/* Why the last platform_library_open failed. */
void platform_library_error(char *out, size_t size);
/* pythonfmu's library (the fallback), with what it needs to load first (Windows: the
 * python3.dll beside the running CPython's DLL, which pythonfmu's DLL imports). */
void *platform_open_wrapper(const char *path);
/* ``finalize`` to run at process exit before the libraries' own destructors (POSIX:
 * __cxa_atexit); nothing on Windows, where it was not checked. */
void platform_exit_handler(void (*finalize)(void *));

/* A CPython library already in the process: 1 with a handle for platform_library_symbol
 * in ``library`` and its file in ``file``; else 0 (``file`` "" or, when a libpython is
 * loaded but its symbols are out of reach, its name). */
int platform_loaded_python(void **library, char *file, size_t size);

/* The subprocess of a probe: run ``argv`` (argv[0] the program, NULL-terminated) without a
 * shell, stdin empty, stdout and stderr captured, PYTHONHOME and PYTHONUTF8 left out of
 * its environment, ended after ``timeout_s``. */
typedef struct {
    char *data;
    size_t size, limit; /* data holds limit + 1 bytes */
} Buffer;

enum Ending { RAN_NOT_STARTED, RAN_TIMED_OUT, RAN_EXITED, RAN_KILLED, RAN_UNKNOWN };

typedef struct {
    enum Ending ending;
    unsigned long code; /* RAN_EXITED: the exit status; RAN_KILLED: the signal */
    char error[256];    /* RAN_NOT_STARTED: why */
} Ran;

void platform_run(const char *const argv[], int timeout_s, Buffer *out, Buffer *err, Ran *ran);

/* ``text`` into a Buffer (at most its limit). */
void buffer_append(Buffer *b, const char *text, size_t n);

#endif
