/* Find a Python for the process and start it (once per process).
 *
 * Written by hand because no library does this job: an FMI host may be any program, with
 * or without Python, on a machine the FMU has just been copied to.
 *
 * The candidates, in this order; the first that can run the FMU is used:
 * 1. the Python running in this process (a Python host such as fmpy, or a host that
 *    started libpython itself): used as it is, or refused, never joined by a second
 *    CPython. A libpython loaded but not started admits only a candidate using that file;
 * 2. AUV_FMU_PYTHON: a Python executable, or a virtual environment's folder (its
 *    bin/python3, else bin/python; on Windows its Scripts\python.exe);
 * 3. the Python the FMU was built with (resources/fmu_runtime.txt);
 * 4. python3, then python, on PATH (on Windows python, then the launcher's py -3).
 * Each candidate executable is asked once per process, in one subprocess (probe.c): its
 * version, shared libpython, base prefix, standard library, sys.path, numpy and numba. It
 * can run the FMU when it is CPython >= 3.9 with a shared libpython, imports numpy, and
 * its base prefix holds that version's standard library. The runtime then loads its
 * libpython (RTLD_GLOBAL: numpy's extension modules resolve CPython's symbols from it;
 * on Windows python3X.dll, which extension modules import by name),
 * checks that the library is the version the executable said, sets the interpreter's
 * home to the base prefix (Py_SetPythonHome wins over a PYTHONHOME in the host's
 * environment), initialises it without signal handlers, gives it the candidate's
 * sys.path (with its site-packages' .pth files) and sys.executable, releases the GIL, and
 * never finalises it: no FMU owns Python.
 * When no candidate can: one Error line per candidate, saying why it was passed over and
 * what would fix it, and fmi2Instantiate returns NULL.
 * What differs between linux64 and win64 is in platform_posix.c / platform_win32.c.
 */
#include "loader.h"
#include "probe.h"
#include "python.h"

#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CANDIDATES 5
#define SHOWN_SIZE (PATH_SIZE + 64)

typedef struct {
    char shown[SHOWN_SIZE];      /* how the line names it */
    char executable[PATH_SIZE]; /* "" when there is none; then ``why`` says so */
    const char *argument;        /* given before the probe's -c (py -3), or NULL */
    char why[LINE_SIZE];         /* why it was passed over */
} Candidate;

typedef struct Probed {
    char executable[PATH_SIZE];
    const char *argument;
    Answer answer;
    struct Probed *next;
} Probed;

static int ready;       /* Python runs in the process and suits the FMU */
static Probed *probed;  /* every candidate asked so far (each is asked once) */

static const Answer *ask(const char *executable, const char *argument)
{
    for (Probed *p = probed; p; p = p->next) {
        if (!strcmp(p->executable, executable) && p->argument == argument) return &p->answer;
    }
    Probed *p = calloc(1, sizeof *p);
    if (!p) return NULL;
    snprintf(p->executable, sizeof p->executable, "%s", executable);
    p->argument = argument;
    probe(executable, argument, &p->answer);
    p->next = probed;
    probed = p;
    return &p->answer;
}

/* ---- a libpython already in the process ---------------------------------------------- */

/* A CPython in the process: 1 with its file in ``loaded`` and its API resolved, or 0
 * (``loaded`` names a libpython loaded but out of reach, if there is one). */
static int python_in_process(char *loaded)
{
    void *library = NULL;
    const char *missing = "";
    /* resolved once: another thread may be reading the API while this one asks again */
    return platform_loaded_python(&library, loaded, PATH_SIZE) &&
           (py.IsInitialized || python_resolve(library, &missing));
}

/* The Python running in this process: "" if it can run the FMU, else why not. */
static void check_running(const char *loaded, char *why, size_t n)
{
    int major, minor;
    char said[72];
    /* the GIL held: no copy starts it meanwhile */
    if (!python_version(&major, &minor, said, sizeof said)) {
        snprintf(why, n,
                 "its version \"%s\" (%s) is not major.minor (whole numbers, each at most %d)",
                 said, loaded, INT_MAX);
        return;
    }
    if (major < 3 || (major == 3 && minor < 9)) {
        snprintf(why, n, "Python %d.%d (%s) is too old: the FMU needs CPython >= 3.9", major,
                 minor, loaded);
        return;
    }
    int gil = py.GILState_Ensure();
    PyObject *check = python_helper("check");
    PyObject *args = check ? py.Tuple_New(0) : NULL;
    PyObject *result = args ? py.Call(check, args, NULL) : NULL;
    const char *text = result ? py.Unicode_AsUTF8(result) : NULL;
    if (text) {
        snprintf(why, n, "%s", text);
    } else {
        char error[512];
        python_error(error, sizeof error);
        snprintf(why, n, "cannot be asked what it imports (%s)", error);
    }
    PyObject *objects[] = {result, args, check};
    for (size_t i = 0; i < 3; i++) {
        if (objects[i]) py.DecRef(objects[i]);
    }
    py.GILState_Release(gil);
}

/* ---- the candidates ------------------------------------------------------------------ */

static void variable_candidate(Candidate *k)
{
    char value[PATH_SIZE + 1]; /* a byte more: a value that does not fit is seen */
    const char *named = platform_getenv(PYTHON_VARIABLE, value, sizeof value);
    if (!named || !named[0]) {
        snprintf(k->shown, sizeof k->shown, "%s", PYTHON_VARIABLE);
        snprintf(k->why, sizeof k->why,
                 "not set (set it to a Python executable or a virtual environment's folder: "
                 "CPython >= 3.9 with a shared libpython and numpy)");
        return;
    }
    snprintf(k->shown, sizeof k->shown, "%s=%s", PYTHON_VARIABLE, named);
    if (strlen(named) >= PATH_SIZE) { /* cut short, it would name another file */
        snprintf(k->shown, sizeof k->shown, "%s=%.*s...", PYTHON_VARIABLE,
                 (int)whole_characters(named, 200), named);
        snprintf(k->why, sizeof k->why, "longer than the runtime's %d bytes", PATH_SIZE - 1);
        return;
    }
    if (!platform_is_directory(named)) {
        snprintf(k->executable, sizeof k->executable, "%s", named);
        return;
    }
    char tried[256] = "";
    for (int i = 0; VENV_PYTHONS[i] && !k->executable[0]; i++) {
        int joined = snprintf(k->executable, sizeof k->executable, "%s%s%s", named,
                              PATH_SEPARATOR, VENV_PYTHONS[i]);
        /* one that does not fit is none: cut short, it would name another file */
        if (joined < 0 || (size_t)joined >= sizeof k->executable ||
            !path_exists(k->executable)) {
            k->executable[0] = '\0';
        }
        size_t used = strlen(tried);
        snprintf(tried + used, sizeof tried - used, "%s%s", i ? " or " : "", VENV_PYTHONS[i]);
    }
    if (!k->executable[0]) {
        snprintf(k->why, sizeof k->why,
                 "the folder has no %s (expected a virtual environment's folder or a Python "
                 "executable)",
                 tried);
    }
}

static void list_candidates(Instance *c, Candidate k[CANDIDATES])
{
    memset(k, 0, CANDIDATES * sizeof *k);
    snprintf(k[0].shown, sizeof k[0].shown, "the Python running in this process");
    snprintf(k[0].why, sizeof k[0].why, "none runs");
    variable_candidate(&k[1]);
    snprintf(k[2].shown, sizeof k[2].shown, "the build's Python%s%s",
             c->record.build_python[0] ? " " : "", c->record.build_python);
    snprintf(k[2].executable, sizeof k[2].executable, "%s", c->record.build_python);
    if (!c->record.build_python[0]) {
        snprintf(k[2].why, sizeof k[2].why, "not recorded in resources/%s", RECORD_FILE);
    }
    for (int i = 0; i < 2; i++) {
        Candidate *p = &k[3 + i];
        char name[64];
        snprintf(name, sizeof name, "%s%s%s", PATH_PYTHONS[i].name,
                 PATH_PYTHONS[i].argument ? " " : "",
                 PATH_PYTHONS[i].argument ? PATH_PYTHONS[i].argument : "");
        p->argument = PATH_PYTHONS[i].argument;
        snprintf(p->shown, sizeof p->shown, "%s on PATH", name);
        if (!platform_on_path(PATH_PYTHONS[i].name, p->executable, sizeof p->executable)) {
            snprintf(p->why, sizeof p->why, "not found");
        } else {
            snprintf(p->shown, sizeof p->shown, "%s on PATH (%s)", name, p->executable);
        }
    }
}

/* Why the asked candidate cannot run the FMU (into ``why``), or 0 if it can. */
static int unsuitable(const Answer *a, const char *loaded, char *why, size_t n)
{
    if (a->bad_version[0]) {
        return snprintf(why, n,
                        "said its version is \"%s\", not major.minor.micro (three whole "
                        "numbers, each at most %d)",
                        a->bad_version, INT_MAX);
    }
    if (a->major && (a->major < 3 || (a->major == 3 && a->minor < 9))) {
        return snprintf(why, n, "Python %d.%d.%d is too old: the FMU needs CPython >= 3.9",
                        a->major, a->minor, a->micro);
    }
    if (!a->answered) return snprintf(why, n, "%s", a->failure);
    if (a->too_long[0]) {
        return snprintf(why, n, "said a %s path longer than the runtime's %d bytes", a->too_long,
                        PATH_SIZE - 1);
    }
    if (strcmp(a->implementation, "CPython")) {
        return snprintf(why, n, "is %s, not CPython", a->implementation);
    }
    if (!a->libpython[0]) {
        return snprintf(why, n,
                        "Python %d.%d.%d has no shared libpython (built without "
                        "--enable-shared; pyenv with PYTHON_CONFIGURE_OPTS=--enable-shared, "
                        "conda and Debian's python3 have one)",
                        a->major, a->minor, a->micro);
    }
    if (!a->numpy[0]) {
        return snprintf(why, n,
                        "Python %d.%d.%d cannot import numpy (%s); fix: %s -m pip install numpy",
                        a->major, a->minor, a->micro, a->numpy_error, a->executable);
    }
    /* The standard library: a folder with os.py, or the zip CPython puts on sys.path from
     * the libpython's folder (python313.zip: Windows' embeddable distribution) */
    char os_py[PATH_SIZE + 16], zip[PATH_SIZE + 32];
    snprintf(os_py, sizeof os_py, "%s%sos.py", a->stdlib, PATH_SEPARATOR);
    const char *lib = a->libpython;
    size_t folder = strlen(lib);
    while (folder && lib[folder - 1] != '/' && lib[folder - 1] != PATH_SEPARATOR[0]) folder--;
    snprintf(zip, sizeof zip, "%.*spython%d%d.zip", (int)folder, lib, a->major, a->minor);
    int in_prefix = !strncmp(a->stdlib, a->base_prefix, strlen(a->base_prefix));
    if (!(in_prefix && path_exists(os_py)) && !path_exists(zip)) {
        return snprintf(why, n, "its base prefix %s holds no standard library (no %s nor %s)",
                        a->base_prefix, os_py, zip);
    }
    if (loaded[0] && !platform_same_file(a->libpython, loaded)) {
        return snprintf(why, n,
                        "uses %s, but %s is already loaded in this process (never two "
                        "CPythons in one process)",
                        a->libpython, loaded);
    }
    return 0;
}

/* The candidate's sys.path as a Python list, then helpers.configure(path, executable). */
static int configure(const Answer *a, char *why, size_t n)
{
    PyObject *path = py.List_New((Py_ssize_t)a->paths);
    const char *entry = a->path;
    for (size_t i = 0; path && i < a->paths; i++, entry += strlen(entry) + 1) {
        py.List_SetItem(path, (Py_ssize_t)i, py.Unicode_DecodeFSDefault(entry));
    }
    PyObject *function = python_helper("configure");
    PyObject *args = py.Tuple_New(2);
    PyObject *result = NULL;
    if (path && function && args) {
        py.Tuple_SetItem(args, 0, path);
        py.Tuple_SetItem(args, 1, py.Unicode_DecodeFSDefault(a->executable));
        path = NULL; /* the tuple owns it */
        result = py.Call(function, args, NULL);
    }
    if (!result) {
        char error[512];
        python_error(error, sizeof error);
        snprintf(why, n, "Python started, but its search path could not be set (%s)", error);
    }
    PyObject *objects[] = {result, args, function, path};
    for (size_t i = 0; i < 4; i++) {
        if (objects[i]) py.DecRef(objects[i]);
    }
    return result != NULL;
}

/* Initialise the candidate's libpython, loaded and checked: 1, or 0 with ``why``. */
static int initialise(const Answer *a, char *why, size_t n)
{
    platform_library_open(a->libpython, 1); /* loaded already: now for extensions too */
    wchar_t *home = py.DecodeLocale(a->base_prefix, NULL);
    py.SetPythonHome(home); /* copies it (3.8 and later) */
    if (home) py.RawFree(home);
    /* Python's UTF-8 mode (PEP 540; the default from 3.15, PEP 686): file names are UTF-8
     * whatever the host's locale. Under the C locale of a host started without LANG (env
     * -i, a service, a container) Python would take them for ASCII, and an FMU extracted
     * under a folder with a non-ASCII name could not be imported. */
    if (py.UTF8Mode) *py.UTF8Mode = 1;
    py.InitializeEx(0); /* 0: no signal handlers, the host keeps its own */
    int ok = configure(a, why, n);
    py.SaveThread(); /* the GIL is taken with PyGILState_Ensure in every call */
    return ok;
}

/* Load the candidate's libpython, check it, initialise it; 1, or 0 with ``why``. */
static int start(const Answer *a, char *why, size_t n)
{
    void *library = platform_library_open(a->libpython, 0);
    const char *missing = "";
    int major = 0, minor = 0, readable = 1;
    char said[72] = "";
    if (!library) {
        char error[LINE_SIZE / 2];
        platform_library_error(error, sizeof error);
        snprintf(why, n, "cannot load its libpython %s (%s)", a->libpython, error);
        return 0;
    }
    if (!python_resolve(library, &missing)) {
        snprintf(why, n, "its libpython %s lacks %s (the runtime needs CPython 3.9 or later)",
                 a->libpython, missing);
    } else {
        /* another copy of this runtime (another FMU, another extraction) may be starting
         * it, or reading its version, in another thread right now: checked and started
         * under one lock */
        void *held = platform_hold_python(a->libpython);
        int started = py.IsInitialized(); /* meanwhile, by a copy that checked it */
        if (!started) { /* Py_GetVersion: one static buffer */
            readable = python_version(&major, &minor, said, sizeof said);
        }
        int same = started || (readable && major == a->major && minor == a->minor);
        int ok = same && (started || initialise(a, why, n));
        platform_release_python(held);
        if (same) return ok;
        if (!readable) {
            snprintf(why, n,
                     "its libpython %s says its version is \"%s\", not major.minor (whole "
                     "numbers, each at most %d)",
                     a->libpython, said, INT_MAX);
        } else {
            snprintf(why, n, "its libpython %s is Python %d.%d, not %d.%d", a->libpython,
                     major, minor, a->major, a->minor);
        }
    }
    memset(&py, 0, sizeof py);
    platform_library_close(library);
    return 0;
}

/* ---- choosing ------------------------------------------------------------------------ */

/* One line to the host: ``format`` as printf's, every % of the result doubled. */
__attribute__((format(printf, 3, 4))) static void say(Instance *c, fmi2Status status,
                                                      const char *format, ...)
{
    char line[LINE_SIZE + SHOWN_SIZE + 128];
    va_list args;
    va_start(args, format);
    vsnprintf(line, sizeof line, format, args);
    va_end(args);
    char escaped[2 * sizeof line];
    escape(line, escaped, sizeof escaped);
    instance_log(c, status, status >= fmi2Error ? "logStatusError" : "logAll", escaped);
}

static int use_running(Instance *c, const char *loaded)
{
    char why[LINE_SIZE] = "";
    if (py.IsFinalizing && py.IsFinalizing()) {
        snprintf(why, sizeof why, "it is shutting down");
    } else {
        check_running(loaded, why, sizeof why);
    }
    if (!why[0]) return 1;
    say(c, fmi2Error, "no Python for this FMU: 1. %s: %s", "the Python running in this process",
        why);
    say(c, fmi2Error, "no Python for this FMU: %s: %s", "the other candidates",
        "not tried: a Python runs in this process, and two CPythons cannot share one");
    return 0;
}

static int find_and_start(Instance *c)
{
    char loaded[PATH_SIZE] = "";
    if (python_in_process(loaded) && py.IsInitialized()) return use_running(c, loaded);
    Candidate k[CANDIDATES];
    list_candidates(c, k);
    if (loaded[0]) {
        snprintf(k[0].why, sizeof k[0].why,
                 "%s is loaded but not started: only a candidate using it can be", loaded);
    }
    for (int i = 1; i < CANDIDATES; i++) {
        if (k[i].why[0]) continue;
        const Answer *a =
            path_exists(k[i].executable) ? ask(k[i].executable, k[i].argument) : NULL;
        if (!path_exists(k[i].executable)) {
            snprintf(k[i].why, sizeof k[i].why, "%s",
                     i == 2 ? "does not exist (the FMU was built in an environment that is not "
                              "on this machine)"
                            : "no such file or folder");
        } else if (!a) {
            snprintf(k[i].why, sizeof k[i].why, "out of memory");
        } else if (!unsuitable(a, loaded, k[i].why, sizeof k[i].why) &&
                   start(a, k[i].why, sizeof k[i].why)) {
            char used[LINE_SIZE];
            snprintf(used, sizeof used, "Python %d.%d.%d (%s), numba %s", a->major, a->minor,
                     a->micro, a->libpython, a->numba ? "installed" : "not installed");
            for (int j = 1; j < i; j++) { /* named, found, yet not used: say why */
                if (k[j].executable[0]) say(c, fmi2Warning, "passed over %s: %s", k[j].shown, k[j].why);
            }
            say(c, fmi2OK, "the FMU runs in %s: %s", k[i].shown, used);
            return 1;
        }
        for (int j = i + 1; j < CANDIDATES && python_alive(); j++) {
            snprintf(k[j].why, sizeof k[j].why, "not tried: %s", "the Python started above runs");
        }
    }
    for (int i = 0; i < CANDIDATES; i++) {
        char what[SHOWN_SIZE + 8];
        snprintf(what, sizeof what, "%d. %s", i + 1, k[i].shown);
        say(c, fmi2Error, "no Python for this FMU: %s: %s", what, k[i].why);
    }
    return 0;
}

/* A thread may call in holding the GIL (a Python host that keeps it across its FMI calls,
 * in one thread, while a parallel master's worker makes another instance): when Python
 * runs already, this lock is never held while waiting for the GIL, nor while Python code
 * runs (the GIL may pass to another thread then, which may want this lock). */
int runtime_python(Instance *c)
{
    char loaded[PATH_SIZE] = "";
    platform_lock(LOCK_RUNTIME);
    int ok = ready && python_alive();
    int running = !ok && python_in_process(loaded) && python_alive();
    if (!ok && !running) ok = ready = find_and_start(c); /* none runs: no GIL to wait for */
    platform_unlock(LOCK_RUNTIME);
    if (ok || !running) return ok;
    int gil = py.GILState_Ensure(); /* then Python code, never under our lock: while it
                                      * runs, another thread may take the GIL */
    ok = use_running(c, loaded);
    platform_lock(LOCK_RUNTIME);
    ready = ready || ok;
    platform_unlock(LOCK_RUNTIME);
    py.GILState_Release(gil);
    return ok;
}

int runtime_gone(void)
{
    platform_lock(LOCK_RUNTIME); /* another thread may be resolving the API, or starting it */
    int gone = python_gone();
    platform_unlock(LOCK_RUNTIME);
    return gone;
}
