/* Find and start the Python runtime, then load pythonfmu's wrapper library (once per process).
 *
 * Written by hand because no library does this job: pythonfmu's binary expects the host to
 * have CPython's symbols loaded and an interpreter that can import the FMU's packages.
 *
 * Where Python comes from, in this order:
 * 1. A Python already running in the process (a Python host such as fmpy, or a host that
 *    preloaded libpython and started it): used as it is, nothing is changed.
 * 2. The variable AUV_FMU_PYTHON, naming a Python executable or a virtual environment's
 *    folder: that Python is asked (``python -c``) for its libpython, base prefix and
 *    site-packages.
 * 3. ``resources/python_runtime.txt``, written by the build: the same three paths (and
 *    the executable) of the environment the FMU was built in.
 * The loader then loads libpython with RTLD_GLOBAL (pythonfmu's library and compiled
 * extensions such as numpy's resolve CPython's symbols from it), sets the interpreter's
 * home to the base prefix (unless the host set PYTHONHOME), initialises it without signal
 * handlers, puts the site-packages folder (with its .pth files) on sys.path ahead of the
 * base installation's, releases the GIL and never finalises the interpreter: no FMU owns
 * Python, so freeing or unloading one FMU cannot stop it under another.
 *
 * pythonfmu 0.7's wrapper releases its interpreter guard twice at process exit (a static
 * destructor, then its ``finalizePythonInterpreter``): right after loading the wrapper the
 * loader registers ``finalizePythonInterpreter`` as an exit handler, which runs first
 * (exit handlers run last-registered first) while the guard is alive and leaves nothing
 * for the two later releases (fmu_runtime/exit_guard.py does the same from Python for a
 * wrapper loaded without this loader).
 */
#ifndef _WIN32
#define _GNU_SOURCE /* dladdr, RTLD_DEFAULT */
#endif
#include "loader.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <wchar.h>

#ifdef _WIN32
#include <windows.h>
typedef HMODULE Library;
#define PATH_SEP "\\"
#define popen _popen
#define pclose _pclose
static SRWLOCK runtime_lock = SRWLOCK_INIT;
static void lock(void) { AcquireSRWLockExclusive(&runtime_lock); }
static void unlock(void) { ReleaseSRWLockExclusive(&runtime_lock); }
static Library open_global(const char *path) { return LoadLibraryA(path); }
static Library open_local(const char *path) { return LoadLibraryA(path); }
static void *symbol(Library library, const char *name)
{
    return library ? (void *)GetProcAddress(library, name) : NULL;
}
static Library loaded_python(const char *libpython)
{
    const char *base = strrchr(libpython, '\\');
    return libpython[0] ? GetModuleHandleA(base ? base + 1 : libpython) : NULL;
}
static int own_path(char *out, size_t size)
{
    HMODULE self = NULL;
    GetModuleHandleExA(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS |
                           GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                       (LPCSTR)&loader_runtime, &self);
    DWORD n = GetModuleFileNameA(self, out, (DWORD)size);
    return n > 0 && n < size;
}
static const char *library_error(void) { return "LoadLibrary failed"; }
static void guard_exit(Library wrapper) { (void)wrapper; } /* DllMain runs in order there */
#else
#include <dlfcn.h>
#include <pthread.h>
typedef void *Library;
#define PATH_SEP "/"
static pthread_mutex_t runtime_lock = PTHREAD_MUTEX_INITIALIZER;
static void lock(void) { pthread_mutex_lock(&runtime_lock); }
static void unlock(void) { pthread_mutex_unlock(&runtime_lock); }
static Library open_global(const char *path) { return dlopen(path, RTLD_NOW | RTLD_GLOBAL); }
static Library open_local(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol(Library library, const char *name) { return dlsym(library, name); }
static Library loaded_python(const char *libpython)
{
    (void)libpython;
    return dlsym(RTLD_DEFAULT, "Py_IsInitialized") ? RTLD_DEFAULT : NULL;
}
static int own_path(char *out, size_t size)
{
    Dl_info info;
    if (!dladdr((void *)&loader_runtime, &info) || !info.dli_fname) return 0;
    return snprintf(out, size, "%s", info.dli_fname) < (int)size;
}
static const char *library_error(void)
{
    const char *e = dlerror();
    return e ? e : "unknown error";
}
extern int __cxa_atexit(void (*)(void *), void *, void *);
static void guard_exit(Library wrapper)
{
    void (*finalize)(void *) = (void (*)(void *))dlsym(wrapper, "finalizePythonInterpreter");
    if (finalize) __cxa_atexit(finalize, NULL, NULL);
}
#endif

#define PATH_SIZE 4096

typedef struct {
    char libpython[PATH_SIZE];
    char home[PATH_SIZE];
    char site[PATH_SIZE];
    char executable[PATH_SIZE];
} Runtime;

static Wrapper wrapper;
static int wrapper_ready;

/* key=value lines (libpython, home, site, executable); unknown keys are ignored. */
static void parse_runtime(FILE *in, Runtime *rt)
{
    char line[PATH_SIZE + 32];
    while (fgets(line, sizeof line, in)) {
        line[strcspn(line, "\r\n")] = '\0';
        char *value = strchr(line, '=');
        if (!value) continue;
        *value++ = '\0';
        char *field = !strcmp(line, "libpython")    ? rt->libpython
                      : !strcmp(line, "home")       ? rt->home
                      : !strcmp(line, "site")       ? rt->site
                      : !strcmp(line, "executable") ? rt->executable
                                                    : NULL;
        if (field) snprintf(field, PATH_SIZE, "%s", value);
    }
}

static const char QUERY[] =
    "import os,sys,sysconfig as s;v=s.get_config_var;"
    "print(\"libpython=\"+(os.path.join(sys.base_prefix,\"python%d%d.dll\"%sys.version_info[:2])"
    " if os.name==\"nt\" else os.path.join(v(\"LIBDIR\") or \"\",v(\"INSTSONAME\") or \"\")));"
    "print(\"home=\"+sys.base_prefix);print(\"site=\"+s.get_paths()[\"purelib\"]);"
    "print(\"executable=\"+sys.executable)";

/* Ask the Python named by AUV_FMU_PYTHON (an executable or a venv folder) for its paths. */
static int query_python(const char *named, Runtime *rt, char *why, size_t n)
{
    char exe[PATH_SIZE], command[2 * PATH_SIZE];
    FILE *probe = fopen(named, "rb");
    if (probe) {
        fclose(probe);
        snprintf(exe, sizeof exe, "%s", named);
    } else {
#ifdef _WIN32
        snprintf(exe, sizeof exe, "%s\\Scripts\\python.exe", named);
#else
        snprintf(exe, sizeof exe, "%s/bin/python3", named);
#endif
    }
    if (strpbrk(exe, "\"$`")) {
        snprintf(why, n, "%s=%s: the path may not contain \" $ or `", LOADER_PYTHON_VARIABLE,
                 named);
        return 0;
    }
#ifdef _WIN32
    /* cmd.exe: the whole line in one more pair of quotes; the script's quotes as \" */
    char script[2 * sizeof QUERY], *out_char = script;
    for (const char *q = QUERY; *q; q++) {
        if (*q == '"') *out_char++ = '\\';
        *out_char++ = *q;
    }
    *out_char = '\0';
    snprintf(command, sizeof command, "\"\"%s\" -c \"%s\"\"", exe, script);
#else
    snprintf(command, sizeof command, "\"%s\" -c '%s'", exe, QUERY);
#endif
    FILE *out = popen(command, "r");
    if (out) {
        parse_runtime(out, rt);
        if (pclose(out) == 0 && rt->home[0]) return 1;
    }
    snprintf(why, n, "%s=%s: could not run %s to ask for its libpython and site-packages",
             LOADER_PYTHON_VARIABLE, named, exe);
    return 0;
}

static int read_runtime(const char *resources, Runtime *rt, char *why, size_t n)
{
    memset(rt, 0, sizeof *rt);
    const char *named = getenv(LOADER_PYTHON_VARIABLE);
    if (named && named[0]) return query_python(named, rt, why, n);
    char path[PATH_SIZE];
    snprintf(path, sizeof path, "%s" PATH_SEP "python_runtime.txt", resources);
    FILE *in = fopen(path, "r");
    if (!in) {
        snprintf(why, n,
                 "no Python in the process and no %s (the build's record); set %s to a "
                 "Python executable or virtual environment with auv-cosim installed",
                 path, LOADER_PYTHON_VARIABLE);
        return 0;
    }
    parse_runtime(in, rt);
    fclose(in);
    return 1;
}

static void hex(const char *text, char *out)
{
    for (; *text; text++, out += 2) sprintf(out, "%02x", (unsigned char)*text);
    *out = '\0';
}

/* sys.path gets the environment's site-packages (and its .pth files) ahead of the base
 * installation's; sys.executable becomes that environment's Python, not the host. */
static const char BOOTSTRAP[] =
    "import site, sys\n"
    "s, e = bytes.fromhex('%s').decode(), bytes.fromhex('%s').decode()\n"
    "n = len(sys.path)\n"
    "site.addsitedir(s)\n"
    "new = sys.path[n:]\n"
    "del sys.path[n:]\n"
    "i = next((k for k, p in enumerate(sys.path) if p.endswith('site-packages')), n)\n"
    "sys.path[i:i] = new\n"
    "if e: sys.executable = e\n";

typedef struct {
    int (*is_initialized)(void);
    wchar_t *(*decode_locale)(const char *, size_t *);
    void (*set_home)(const wchar_t *);
    void (*initialize_ex)(int);
    int (*run_simple_string)(const char *);
    void *(*save_thread)(void);
    void (*raw_free)(void *);
} PythonApi;

static int start_python(Library python, const Runtime *rt, char *why, size_t n)
{
    PythonApi api = {
        (int (*)(void))symbol(python, "Py_IsInitialized"),
        (wchar_t * (*)(const char *, size_t *)) symbol(python, "Py_DecodeLocale"),
        (void (*)(const wchar_t *))symbol(python, "Py_SetPythonHome"),
        (void (*)(int))symbol(python, "Py_InitializeEx"),
        (int (*)(const char *))symbol(python, "PyRun_SimpleString"),
        (void *(*)(void))symbol(python, "PyEval_SaveThread"),
        (void (*)(void *))symbol(python, "PyMem_RawFree"),
    };
    if (!api.is_initialized || !api.decode_locale || !api.set_home || !api.initialize_ex ||
        !api.run_simple_string || !api.save_thread) {
        snprintf(why, n, "%s lacks the CPython functions the loader needs (Python 3.8-3.14)",
                 rt->libpython);
        return 0;
    }
    if (api.is_initialized()) return 1;
    if (!getenv("PYTHONHOME") && rt->home[0]) {
        wchar_t *home = api.decode_locale(rt->home, NULL);
        api.set_home(home); /* copies it (Python 3.8 and later) */
        if (home && api.raw_free) api.raw_free(home);
    }
    api.initialize_ex(0);
    size_t size = sizeof BOOTSTRAP + 2 * (strlen(rt->site) + strlen(rt->executable));
    char *code = malloc(size), *s = malloc(2 * PATH_SIZE + 1), *e = malloc(2 * PATH_SIZE + 1);
    int failed = !code || !s || !e;
    if (!failed) {
        hex(rt->site, s);
        hex(rt->executable, e);
        snprintf(code, size, BOOTSTRAP, s, e);
        failed = api.run_simple_string(code) != 0;
    }
    free(code);
    free(s);
    free(e);
    api.save_thread(); /* pythonfmu takes the GIL with PyGILState_Ensure in every call */
    if (failed) snprintf(why, n, "could not add %s to Python's search path", rt->site);
    return !failed;
}

static int ensure_python(const char *resources, char *why, size_t n)
{
    Runtime rt;
    Library python = loaded_python("");
    if (python) {
        int (*is_initialized)(void) = (int (*)(void))symbol(python, "Py_IsInitialized");
        if (is_initialized && is_initialized()) return 1; /* a Python host: change nothing */
    }
    if (!read_runtime(resources, &rt, why, n)) return 0;
    if (!python) python = loaded_python(rt.libpython);
    if (!python) {
        if (!rt.libpython[0]) {
            snprintf(why, n,
                     "the Python at %s has no shared libpython; set %s to a Python executable "
                     "or virtual environment whose Python has one (pyenv, conda, Debian's)",
                     rt.home, LOADER_PYTHON_VARIABLE);
            return 0;
        }
        python = open_global(rt.libpython);
        if (!python) {
            snprintf(why, n,
                     "cannot load libpython %s (%s); set %s to a Python executable or virtual "
                     "environment with auv-cosim installed",
                     rt.libpython, library_error(), LOADER_PYTHON_VARIABLE);
            return 0;
        }
    }
    return start_python(python, &rt, why, n);
}

#define RESOLVE(field, name) wrapper.field = (void *)symbol(library, name)

static void resolve(Library library)
{
    RESOLVE(setDebugLogging, "fmi2SetDebugLogging");
    RESOLVE(instantiate, "fmi2Instantiate");
    RESOLVE(freeInstance, "fmi2FreeInstance");
    RESOLVE(setupExperiment, "fmi2SetupExperiment");
    RESOLVE(enterInitializationMode, "fmi2EnterInitializationMode");
    RESOLVE(exitInitializationMode, "fmi2ExitInitializationMode");
    RESOLVE(terminate, "fmi2Terminate");
    RESOLVE(reset, "fmi2Reset");
    RESOLVE(getReal, "fmi2GetReal");
    RESOLVE(getInteger, "fmi2GetInteger");
    RESOLVE(getBoolean, "fmi2GetBoolean");
    RESOLVE(getString, "fmi2GetString");
    RESOLVE(setReal, "fmi2SetReal");
    RESOLVE(setInteger, "fmi2SetInteger");
    RESOLVE(setBoolean, "fmi2SetBoolean");
    RESOLVE(setString, "fmi2SetString");
    RESOLVE(getFMUstate, "fmi2GetFMUstate");
    RESOLVE(setFMUstate, "fmi2SetFMUstate");
    RESOLVE(freeFMUstate, "fmi2FreeFMUstate");
    RESOLVE(serializedFMUstateSize, "fmi2SerializedFMUstateSize");
    RESOLVE(serializeFMUstate, "fmi2SerializeFMUstate");
    RESOLVE(deSerializeFMUstate, "fmi2DeSerializeFMUstate");
    RESOLVE(getDirectionalDerivative, "fmi2GetDirectionalDerivative");
    RESOLVE(setRealInputDerivatives, "fmi2SetRealInputDerivatives");
    RESOLVE(getRealOutputDerivatives, "fmi2GetRealOutputDerivatives");
    RESOLVE(doStep, "fmi2DoStep");
    RESOLVE(cancelStep, "fmi2CancelStep");
    RESOLVE(getStatus, "fmi2GetStatus");
    RESOLVE(getRealStatus, "fmi2GetRealStatus");
    RESOLVE(getIntegerStatus, "fmi2GetIntegerStatus");
    RESOLVE(getBooleanStatus, "fmi2GetBooleanStatus");
    RESOLVE(getStringStatus, "fmi2GetStringStatus");
}

/* pythonfmu's library: this library's own file name with "_pythonfmu" before the suffix. */
static int load_wrapper(char *why, size_t n)
{
    char path[PATH_SIZE];
    if (!own_path(path, sizeof path - 16)) {
        snprintf(why, n, "cannot find the loader's own file");
        return 0;
    }
    char *dot = strrchr(path, '.');
    char suffix[16];
    snprintf(suffix, sizeof suffix, "%s", dot ? dot : "");
    snprintf(dot ? dot : path + strlen(path), 32, "_pythonfmu%s", suffix);
    Library library = open_local(path);
    if (!library) {
        snprintf(why, n, "cannot load pythonfmu's library %s (%s)", path, library_error());
        return 0;
    }
    guard_exit(library);
    resolve(library);
    if (!wrapper.instantiate || !wrapper.freeInstance || !wrapper.doStep) {
        snprintf(why, n, "%s is not an FMI 2.0 co-simulation library", path);
        return 0;
    }
    return 1;
}

const Wrapper *loader_runtime(const char *resources, char *why, size_t why_size)
{
    lock();
    int ok = wrapper_ready || (ensure_python(resources, why, why_size) && load_wrapper(why, why_size));
    wrapper_ready = ok;
    unlock();
    return ok ? &wrapper : NULL;
}
