/* platform.h on win64: LoadLibraryExW and GetProcAddress, SRW locks, CreateProcessW with
 * pipes. Paths and texts are UTF-8 inside the runtime and UTF-16 at each call into
 * Windows (the W functions: any path, whatever the ANSI code page).
 *
 * Cross-compiled here (zig cc -target x86_64-windows-gnu) with -Wall -Wextra -Werror, its
 * exports and imports read from the DLL, and run under Wine in a C host
 * (tests/fmu_runtime/test_win64_runtime.py); NOT run on Windows (no Windows machine).
 *
 * The probe's subprocess is written by hand for the reasons of platform_posix.c (no shell,
 * nothing on the host's console, a deadline): CreateProcessW with the program's path (no
 * search), the command line quoted for the MSVC runtime's parser, only the three standard
 * handles inherited, no console window, the environment without PYTHONHOME and PYTHONUTF8.
 */
#ifndef WIN32_LEAN_AND_MEAN
#define WIN32_LEAN_AND_MEAN
#endif
#include "platform.h"

#include <windows.h>

#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <wchar.h>

#define WIDE_PATH 32768 /* the longest path Windows takes, in UTF-16 units */
#define LAST_MINOR 20   /* python3<minor>.dll looked for in the process: 3.0 to 3.20 */

const char *const VENV_PYTHONS[] = {"Scripts\\python.exe", NULL};
const PathPython PATH_PYTHONS[2] = {{"python", NULL}, {"py", "-3"}};

/* ---- text ---------------------------------------------------------------------------- */

/* UTF-8 as UTF-16 (malloc'd), or NULL when it is not UTF-8 or memory runs out. */
static wchar_t *wide(const char *text)
{
    int n = MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, text, -1, NULL, 0);
    wchar_t *out = n > 0 ? malloc((size_t)n * sizeof *out) : NULL;
    if (out && MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, text, -1, out, n) != n) {
        free(out);
        return NULL;
    }
    return out;
}

/* UTF-16 as UTF-8 into ``out``; 0 ("" in out) when it does not fit. */
static int narrow(const wchar_t *text, char *out, size_t size)
{
    int room = size > INT_MAX ? INT_MAX : (int)size;
    if (room > 0 && WideCharToMultiByte(CP_UTF8, 0, text, -1, out, room, NULL, NULL) > 0) {
        return 1;
    }
    if (size) out[0] = '\0';
    return 0;
}

/* Windows' text for an error code, without its final period and line break. */
static void system_message(DWORD code, char *out, size_t size)
{
    wchar_t text[512];
    DWORD n = FormatMessageW(FORMAT_MESSAGE_FROM_SYSTEM | FORMAT_MESSAGE_IGNORE_INSERTS, NULL,
                             code, 0, text, 512, NULL);
    while (n > 0 && (text[n - 1] == L'\r' || text[n - 1] == L'\n' || text[n - 1] == L'.')) n--;
    text[n] = L'\0';
    char said[1024];
    if (!n || !narrow(text, said, sizeof said)) said[0] = '\0';
    snprintf(out, size, "error %lu%s%s", (unsigned long)code, said[0] ? ": " : "", said);
}

/* ---- locks, environment, files ------------------------------------------------------- */

static SRWLOCK locks[LOCKS] = {SRWLOCK_INIT, SRWLOCK_INIT};

void platform_lock(int which) { AcquireSRWLockExclusive(&locks[which]); }
void platform_unlock(int which) { ReleaseSRWLockExclusive(&locks[which]); }

void *platform_hold_python(const char *libpython)
{
    (void)libpython; /* one mutex per process, whichever CPython */
    char name[64];
    snprintf(name, sizeof name, "Local\\auv-fmu-runtime-python-%lu",
             (unsigned long)GetCurrentProcessId());
    wchar_t *w = wide(name);
    HANDLE mutex = w ? CreateMutexW(NULL, FALSE, w) : NULL;
    free(w);
    if (!mutex) return NULL;
    DWORD waited = WaitForSingleObject(mutex, INFINITE);
    if (waited != WAIT_OBJECT_0 && waited != WAIT_ABANDONED) {
        CloseHandle(mutex);
        return NULL;
    }
    return mutex;
}

void platform_release_python(void *held)
{
    if (!held) return;
    ReleaseMutex(held);
    CloseHandle(held);
}

/* The variable's UTF-16 value (malloc'd), or NULL when unset or empty. */
static wchar_t *wide_variable(const char *name)
{
    wchar_t *key = wide(name);
    DWORD n = key ? GetEnvironmentVariableW(key, NULL, 0) : 0;
    wchar_t *value = n > 1 ? malloc(n * sizeof *value) : NULL;
    if (value && GetEnvironmentVariableW(key, value, n) >= n) {
        free(value);
        value = NULL;
    }
    free(key);
    return value;
}

const char *platform_getenv(const char *name, char *out, size_t size)
{
    wchar_t *value = wide_variable(name);
    int ok = value && narrow(value, out, size);
    free(value);
    return ok ? out : NULL;
}

FILE *platform_fopen(const char *path, const char *mode)
{
    wchar_t *w = wide(path), *m = wide(mode);
    FILE *file = w && m ? _wfopen(w, m) : NULL;
    free(w);
    free(m);
    return file;
}

static DWORD attributes(const char *path)
{
    wchar_t *w = path[0] ? wide(path) : NULL;
    DWORD found = w ? GetFileAttributesW(w) : INVALID_FILE_ATTRIBUTES;
    free(w);
    return found;
}

int path_exists(const char *path) { return attributes(path) != INVALID_FILE_ATTRIBUTES; }

int platform_is_directory(const char *path)
{
    DWORD found = attributes(path);
    return found != INVALID_FILE_ATTRIBUTES && (found & FILE_ATTRIBUTE_DIRECTORY);
}

/* The file's volume and index (what tells two paths of one file apart), or 0. */
static int identity(const char *path, BY_HANDLE_FILE_INFORMATION *info)
{
    wchar_t *w = wide(path);
    HANDLE file = w ? CreateFileW(w, 0, FILE_SHARE_READ | FILE_SHARE_WRITE | FILE_SHARE_DELETE,
                                  NULL, OPEN_EXISTING, FILE_FLAG_BACKUP_SEMANTICS, NULL)
                    : INVALID_HANDLE_VALUE;
    free(w);
    if (file == INVALID_HANDLE_VALUE) return 0;
    int ok = GetFileInformationByHandle(file, info) != 0;
    CloseHandle(file);
    return ok;
}

int platform_same_file(const char *a, const char *b)
{
    BY_HANDLE_FILE_INFORMATION x, y;
    return identity(a, &x) && identity(b, &y) &&
           x.dwVolumeSerialNumber == y.dwVolumeSerialNumber &&
           x.nFileIndexHigh == y.nFileIndexHigh && x.nFileIndexLow == y.nFileIndexLow;
}

/* A module's file as UTF-8; 0 if it does not fit. */
static int module_file(HMODULE module, char *out, size_t size)
{
    wchar_t *path = malloc(WIDE_PATH * sizeof *path);
    DWORD n = path ? GetModuleFileNameW(module, path, WIDE_PATH) : 0;
    int ok = n > 0 && n < WIDE_PATH && narrow(path, out, size);
    free(path);
    return ok;
}

int own_path(char *out, size_t size)
{
    HMODULE self = NULL;
    if (!GetModuleHandleExW(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS |
                                GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCWSTR)(void *)&own_path, &self)) {
        return 0;
    }
    return module_file(self, out, size);
}

int platform_on_path(const char *name, char *out, size_t size)
{
    wchar_t *path = wide_variable("PATH");
    char *entries = path ? malloc(4 * wcslen(path) + 1) : NULL;
    int found = 0;
    /* split by hand: strtok's hidden state is the host's too (the probe's reader, too,
     * leaves it alone) */
    char *next = entries && narrow(path, entries, 4 * wcslen(path) + 1) ? entries : NULL;
    while (next && *next && !found) {
        char *entry = next;
        size_t n = strcspn(entry, ";");
        next = entry + n + (entry[n] == ';');
        entry[n] = '\0';
        if (n >= 2 && entry[0] == '"' && entry[n - 1] == '"') { /* "C:\My Tools" */
            entry[n - 1] = '\0';
            entry++;
        }
        /* an entry whose joined path does not fit is passed over: cut short, it would
         * name another file */
        int joined = snprintf(out, size, "%s\\%s.exe", entry, name);
        found = entry[0] && joined >= 0 && (size_t)joined < size && path_exists(out) &&
                !platform_is_directory(out);
    }
    free(entries);
    free(path);
    if (!found) out[0] = '\0';
    return found;
}

/* "/C:/x" -> "C:\x"; "host/share/x" (a URI's host) -> "\\host\share\x"; "localhost/C:/x"
 * -> "C:\x"; then backslashes throughout. */
void platform_local_path(char *path, size_t size)
{
    (void)size;
    size_t n = strlen(path);
    if (path[0] == '/' && ((path[1] >= 'A' && path[1] <= 'Z') ||
                           (path[1] >= 'a' && path[1] <= 'z')) && path[2] == ':') {
        memmove(path, path + 1, n);
    }
    for (char *p = path; *p; p++) {
        if (*p == '/') *p = '\\';
    }
}

/* ---- libraries ----------------------------------------------------------------------- */

static DWORD library_error; /* of the last open; read under the caller's lock */

void *platform_library_open(const char *path, int global)
{
    (void)global; /* Windows binds a DLL's imports by module name: a python3X.dll loaded
                   * once serves every extension module that imports it */
    wchar_t *w = wide(path);
    /* the DLL's own folder searched for what it imports (python3X.dll: vcruntime140.dll) */
    HMODULE module = w ? LoadLibraryExW(w, NULL, LOAD_WITH_ALTERED_SEARCH_PATH) : NULL;
    library_error = module ? 0 : w ? GetLastError() : ERROR_NO_UNICODE_TRANSLATION;
    free(w);
    return (void *)module;
}

void *platform_library_symbol(void *library, const char *name)
{
    return library ? (void *)GetProcAddress((HMODULE)library, name) : NULL;
}

void platform_library_close(void *library) { FreeLibrary((HMODULE)library); }

void platform_library_error(char *out, size_t size) { system_message(library_error, out, size); }

void *platform_open_wrapper(const char *path)
{
    /* pythonfmu's DLL imports python3.dll (the stable ABI's forwarder to python3X.dll),
     * which lies beside the python3X.dll in the process: loaded from there first, it is
     * the one Windows binds that import to */
    void *python = NULL;
    char file[4096];
    if (platform_loaded_python(&python, file, sizeof file)) {
        char *slash = strrchr(file, '\\');
        if (slash && (size_t)(slash + 1 - file) + sizeof "python3.dll" <= sizeof file) {
            memcpy(slash + 1, "python3.dll", sizeof "python3.dll");
            platform_library_open(file, 1); /* held for the process, like Python */
        }
    }
    return platform_library_open(path, 0);
}

void platform_exit_handler(void (*finalize)(void *)) { (void)finalize; }

/* python3<minor>[t].dll (27 for 2.7) as a UTF-16 module name. */
static void python_dll(int minor, int threaded, wchar_t name[16])
{
    char text[16];
    snprintf(text, sizeof text, "python%s%d%s.dll", minor == 27 ? "" : "3", minor,
             threaded ? "t" : "");
    for (int i = 0; i == 0 || text[i - 1]; i++) name[i] = (wchar_t)(unsigned char)text[i];
}

int platform_loaded_python(void **library, char *file, size_t size)
{
    file[0] = '\0';
    *library = NULL;
    for (int minor = 0; minor <= LAST_MINOR + 1; minor++) {
        for (int threaded = 0; threaded < 2; threaded++) {
            wchar_t name[16];
            python_dll(minor > LAST_MINOR ? 27 : minor, threaded, name);
            HMODULE module = GetModuleHandleW(name);
            if (module && module_file(module, file, size)) {
                *library = (void *)module;
                return 1;
            }
        }
    }
    return 0;
}

/* ---- the probe's subprocess ---------------------------------------------------------- */

void buffer_append(Buffer *b, const char *data, size_t n)
{
    if (b->size + n > b->limit) n = b->limit - b->size;
    memcpy(b->data + b->size, data, n);
    b->size += n;
}

/* ``argument`` quoted for the MSVC runtime's parser (CommandLineToArgvW's rules):
 * backslashes are literal except before a quote. */
static void quote(const char *argument, Buffer *line)
{
    if (argument[0] && !strpbrk(argument, " \t\n\v\"")) {
        buffer_append(line, argument, strlen(argument));
        return;
    }
    buffer_append(line, "\"", 1);
    for (const char *p = argument;; p++) {
        size_t slashes = 0;
        while (*p == '\\') p++, slashes++;
        size_t doubled = *p == '\0' ? 2 * slashes : *p == '"' ? 2 * slashes + 1 : slashes;
        for (size_t i = 0; i < doubled; i++) buffer_append(line, "\\", 1);
        if (*p == '\0') break;
        buffer_append(line, p, 1);
    }
    buffer_append(line, "\"", 1);
}

/* The command line (UTF-16, malloc'd), or NULL. */
static wchar_t *command_line(const char *const argv[])
{
    size_t length = 1;
    for (size_t i = 0; argv[i]; i++) length += 3 * strlen(argv[i]) + 3;
    Buffer line = {malloc(length + 1), 0, length};
    if (!line.data) return NULL;
    for (size_t i = 0; argv[i]; i++) {
        if (i) buffer_append(&line, " ", 1);
        quote(argv[i], &line);
    }
    line.data[line.size] = '\0';
    wchar_t *out = wide(line.data);
    free(line.data);
    return out;
}

/* The process's environment block without PYTHONHOME and PYTHONUTF8 (malloc'd), or NULL:
 * why, in platform_posix.c. Names compared without case, as Windows does. */
static wchar_t *child_environment(void)
{
    wchar_t *block = GetEnvironmentStringsW();
    if (!block) return NULL;
    size_t length = 0;
    while (block[length]) length += wcslen(block + length) + 1;
    wchar_t *copy = malloc((length + 2) * sizeof *copy);
    size_t j = 0;
    for (size_t i = 0; copy && block[i]; i += wcslen(block + i) + 1) {
        size_t n = wcslen(block + i);
        if (n >= 11 && (CompareStringOrdinal(block + i, 11, L"PYTHONHOME=", 11, TRUE) == CSTR_EQUAL ||
                        CompareStringOrdinal(block + i, 11, L"PYTHONUTF8=", 11, TRUE) == CSTR_EQUAL)) {
            continue;
        }
        memcpy(copy + j, block + i, (n + 1) * sizeof *copy);
        j += n + 1;
    }
    if (copy) {
        copy[j] = L'\0';
        copy[j + 1] = L'\0'; /* an empty block is two NULs */
    }
    FreeEnvironmentStringsW(block);
    return copy;
}

typedef struct {
    HANDLE read[2];  /* stdout, stderr: ours */
    HANDLE child[3]; /* stdin (NUL), stdout, stderr: the child's */
} Pipes;

static void close_all(HANDLE *handles, int n)
{
    for (int i = 0; i < n; i++) {
        if (handles[i] && handles[i] != INVALID_HANDLE_VALUE) CloseHandle(handles[i]);
        handles[i] = NULL;
    }
}

static int make_pipes(Pipes *p)
{
    SECURITY_ATTRIBUTES inherit = {sizeof inherit, NULL, TRUE};
    memset(p, 0, sizeof *p);
    for (int i = 0; i < 2; i++) {
        if (!CreatePipe(&p->read[i], &p->child[i + 1], &inherit, 0) ||
            !SetHandleInformation(p->read[i], HANDLE_FLAG_INHERIT, 0)) {
            return 0;
        }
    }
    p->child[0] = CreateFileW(L"NUL", GENERIC_READ, FILE_SHARE_READ | FILE_SHARE_WRITE,
                              &inherit, OPEN_EXISTING, 0, NULL);
    return p->child[0] != INVALID_HANDLE_VALUE;
}

/* CreateProcessW inheriting only the child's three handles; 0 with GetLastError. */
static int create(const char *program, wchar_t *line, wchar_t *env, Pipes *p,
                  PROCESS_INFORMATION *info)
{
    SIZE_T size = 0;
    InitializeProcThreadAttributeList(NULL, 1, 0, &size);
    LPPROC_THREAD_ATTRIBUTE_LIST list = malloc(size);
    wchar_t *application = wide(program);
    STARTUPINFOEXW start;
    memset(&start, 0, sizeof start);
    start.StartupInfo.cb = sizeof start;
    start.StartupInfo.dwFlags = STARTF_USESTDHANDLES;
    start.StartupInfo.hStdInput = p->child[0];
    start.StartupInfo.hStdOutput = p->child[1];
    start.StartupInfo.hStdError = p->child[2];
    int ok = list && application && InitializeProcThreadAttributeList(list, 1, 0, &size);
    if (ok) {
        start.lpAttributeList = list;
        ok = UpdateProcThreadAttribute(list, 0, PROC_THREAD_ATTRIBUTE_HANDLE_LIST, p->child,
                                       sizeof p->child, NULL, NULL) &&
             CreateProcessW(application, line, NULL, NULL, TRUE,
                            CREATE_UNICODE_ENVIRONMENT | CREATE_NO_WINDOW |
                                EXTENDED_STARTUPINFO_PRESENT,
                            env, NULL, &start.StartupInfo, info);
        DWORD error = GetLastError();
        DeleteProcThreadAttributeList(list);
        SetLastError(error);
    } else if (!application) {
        SetLastError(ERROR_NO_UNICODE_TRANSLATION);
    }
    free(application);
    free(list);
    return ok;
}

/* Read what is there on each open pipe; a pipe whose writer is gone and which is empty is
 * closed. 1 if anything was read. */
static int read_some(HANDLE read[2], int open[2], Buffer *into[2])
{
    char chunk[4096];
    int got_any = 0;
    for (int i = 0; i < 2; i++) {
        DWORD available = 0, got = 0;
        if (!open[i]) continue;
        if (!PeekNamedPipe(read[i], NULL, 0, NULL, &available, NULL)) {
            open[i] = 0; /* ERROR_BROKEN_PIPE: the child and its children are done with it */
        } else if (available &&
                   ReadFile(read[i], chunk, available < sizeof chunk ? available : sizeof chunk,
                            &got, NULL) &&
                   got) {
            buffer_append(into[i], chunk, got);
            got_any = 1;
        }
    }
    return got_any;
}

/* Both pipes to their end, or the child's exit with nothing left to read, or the
 * deadline; 1 unless the deadline came first. */
static int drain(HANDLE process, HANDLE read[2], Buffer *out, Buffer *err, int timeout_s)
{
    Buffer *into[2] = {out, err};
    int open[2] = {1, 1};
    ULONGLONG deadline = GetTickCount64() + (ULONGLONG)timeout_s * 1000u;
    while (open[0] || open[1]) {
        if (read_some(read, open, into)) continue;
        if (WaitForSingleObject(process, 0) == WAIT_OBJECT_0 && !read_some(read, open, into)) {
            return 1; /* exited, and a grandchild may hold the pipes: done reading */
        }
        if (GetTickCount64() >= deadline) return 0;
        Sleep(2);
    }
    return 1;
}

void platform_run(const char *const argv[], int timeout_s, Buffer *text, Buffer *errors,
                  Ran *ran)
{
    Pipes p = {{NULL, NULL}, {NULL, NULL, NULL}};
    PROCESS_INFORMATION info;
    memset(&info, 0, sizeof info);
    wchar_t *line = command_line(argv);
    wchar_t *env = child_environment();
    int started = line && env && make_pipes(&p) && create(argv[0], line, env, &p, &info);
    DWORD error = started ? 0 : line && env ? GetLastError() : ERROR_NOT_ENOUGH_MEMORY;
    close_all(p.child, 3); /* the child holds its own copies */
    free(line);
    free(env);
    if (!started) {
        close_all(p.read, 2);
        ran->ending = RAN_NOT_STARTED;
        system_message(error, ran->error, sizeof ran->error);
        return;
    }
    CloseHandle(info.hThread);
    int finished = drain(info.hProcess, p.read, text, errors, timeout_s);
    DWORD code = 0;
    if (!finished) TerminateProcess(info.hProcess, 1);
    WaitForSingleObject(info.hProcess, 5000); /* its pipes may close before it is done */
    int known = GetExitCodeProcess(info.hProcess, &code) && code != STILL_ACTIVE;
    ran->ending = !finished ? RAN_TIMED_OUT : known ? RAN_EXITED : RAN_UNKNOWN;
    ran->code = code;
    CloseHandle(info.hProcess);
    close_all(p.read, 2);
}
